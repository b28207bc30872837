"""The ``real`` family: sources, classes, object-wise splits, COLLADA units and SDF poses.

Reader tests use small trees written here; tests on the real FlightGear and Gazebo files skip when
those are absent (FlightGear: data/real-src from ``make data-real``, or /work/fg/root).
"""

import collections
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from data_modules.build import build_dataset
from data_modules.config import load_build_config
from data_modules.real_sources import CLASSES, RealTargetsFamily, normalised_stem, not_object, skip_reason_counts
from radar2shape.errors import UserInputError
from radar2shape.geometry.gazebo import collada_asset, load_gazebo_model, pose_matrix

REPO = Path(__file__).resolve().parents[2]
TRIANGLE_AC = ("AC3Db\nOBJECT world\nkids 1\nOBJECT poly\nname \"{name}\"\nnumvert 4\n0 0 0\n{size} 0 0\n0 {size} 0\n"
               "0 0 {size}\nnumsurf 4\nSURF 0x10\nrefs 3\n0 0 0\n2 0 0\n1 0 0\nSURF 0x10\nrefs 3\n0 0 0\n1 0 0\n"
               "3 0 0\nSURF 0x10\nrefs 3\n1 0 0\n2 0 0\n3 0 0\nSURF 0x10\nrefs 3\n0 0 0\n3 0 0\n2 0 0\nkids 0\n")
BOX_SDF = """<?xml version="1.0"?>
<sdf version="1.6"><model name="crate"><pose>0 0 0 0 0 0</pose>
<link name="base"><pose>1 0 0 0 0 0</pose>
<visual name="v"><pose>0 0 0 0 0 1.5707963267948966</pose><geometry><box><size>1 2 3</size></box></geometry></visual>
<collision name="c"><geometry><box><size>9 9 9</size></box></geometry></collision>
</link></model></sdf>
"""


def fake_sources(tmp_path: Path) -> Path:
    """A FlightGear-like tree (two 737 variants, a light, a ship, a cloud) and one Gazebo model."""
    fg = tmp_path / "fg" / "usr/share/games/flightgear"
    files = {"AI/Aircraft/733/Models/733.ac": 1.0, "AI/Aircraft/738/Models/737-800.ac": 1.2,
             "AI/Aircraft/738/Models/lights/flash.ac": 0.1, "AI/Aircraft/c172/Models/c172p.ac": 0.5,
             "Models/Maritime/Civilian/Tanker.ac": 3.0, "Models/Weather/cloud.ac": 2.0,
             "Models/Buildings/silo.ac": 2.5, "Models/Agriculture/silo.ac": 2.5}  # the same file twice
    for relative, size in files.items():
        (fg / relative).parent.mkdir(parents=True, exist_ok=True)
        (fg / relative).write_text(TRIANGLE_AC.format(name=Path(relative).stem, size=size))
    crate = tmp_path / "gazebo" / "crate"
    crate.mkdir(parents=True)
    (crate / "model.sdf").write_text(BOX_SDF)
    return tmp_path


def sources(tmp_path: Path) -> list[dict]:
    return [{"type": "flightgear_ai", "root": str(tmp_path / "fg"), "up": "y"},
            {"type": "flightgear_models", "root": str(tmp_path / "fg"), "up": "y"},
            {"type": "gazebo", "root": str(tmp_path / "gazebo"), "up": "z"}]


def test_plan_classes_exclusions_and_duplicates(tmp_path):
    family = RealTargetsFamily(sources(fake_sources(tmp_path)))
    tasks = family.plan(None, {"train": 0.8, "val": 0.1, "test": 0.1}, seed=0)
    by_source = {t.source: t for t in tasks}
    assert sorted(by_source) == ["0:AI/Aircraft/733/Models/733.ac", "0:AI/Aircraft/738/Models/737-800.ac",
                                 "0:AI/Aircraft/c172/Models/c172p.ac", "1:Models/Agriculture/silo.ac",
                                 "1:Models/Maritime/Civilian/Tanker.ac", "2:crate"]
    assert [by_source[s].class_name for s in sorted(by_source)] == [
        "airliner", "airliner", "light aircraft", "building", "ship", "other"]
    assert all(t.label == CLASSES.index(t.class_name) for t in tasks)
    reasons = dict(family.excluded)
    assert reasons["AI/Aircraft/738/Models/lights/flash.ac"] == "folder lights/"
    assert reasons["Models/Weather/cloud.ac"] == "folder weather/"
    assert reasons["1:Models/Buildings/silo.ac"] == "same file as 1:Models/Agriculture/silo.ac"


def test_split_is_by_object_group_for_every_seed(tmp_path):
    family = RealTargetsFamily(sources(fake_sources(tmp_path)))
    splits = {"train": 1.0, "val": 1.0, "test": 1.0}
    seen = set()
    for seed in range(40):
        tasks = {t.source: t.split for t in family.plan(None, splits, seed)}
        assert tasks["0:AI/Aircraft/733/Models/733.ac"] == tasks["0:AI/Aircraft/738/Models/737-800.ac"]
        seen.add(tasks["0:AI/Aircraft/733/Models/733.ac"])
    assert seen == {"train", "val", "test"}  # the group does move with the seed: the test could fail
    assert family.plan(None, splits, 3) == family.plan(None, splits, 3)


def test_group_names_and_non_objects():
    assert normalised_stem("MontHse1Grey_Green") == normalised_stem("MontHse1Grey_White") == "monthse"
    assert normalised_stem("CG57") == normalised_stem("CG-57") == normalised_stem("CG47") == "ticonderoga"
    assert normalised_stem("farmhouse2-white") == normalised_stem("farmhouse2") == "farmhouse"
    assert not_object("AI/Aircraft/Lightning/Models/light-red-flare.ac")
    assert not_object("Models/Commercial/medium-glass-office-building.ac") is None
    assert not_object("AI/Aircraft/Lightning/Models/lightning-f1a.ac") is None
    assert not_object("AI/Aircraft/flash2a/Models/flash2a.ac") is None


def test_sdf_poses_place_primitives_and_collisions_are_ignored(tmp_path):
    fake_sources(tmp_path)
    mesh, report = load_gazebo_model(tmp_path / "gazebo" / "crate")
    assert report["parts"] == 1
    assert np.allclose(mesh.extents, [2.0, 1.0, 3.0])  # the 1 x 2 x 3 box turned a quarter about z
    assert np.allclose(mesh.bounds.mean(axis=0), [1.0, 0.0, 0.0])  # moved by the link pose
    assert np.allclose(pose_matrix("0 0 0 0 0 1.5707963267948966")[:3, :3] @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(pose_matrix("0 0 0 1.5707963267948966 0 0")[:3, :3] @ [0, 1, 0], [0, 0, 1])  # roll about x


def test_collada_unit_and_up_axis_are_applied(tmp_path):
    pytest.importorskip("collada", reason="COLLADA needs pycollada (make data-real installs it)")
    from radar2shape.geometry.mesh_io import load_mesh

    path = tmp_path / "tri.dae"
    path.write_text("""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<asset><unit name="inch" meter="0.0254"/><up_axis>Y_UP</up_axis></asset>
<library_geometries><geometry id="g"><mesh>
<source id="p"><float_array id="pa" count="9">0 0 0 10 0 0 0 10 0</float_array>
<technique_common><accessor source="#pa" count="3" stride="3"><param name="X" type="float"/>
<param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
<vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
<triangles count="1"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2</p></triangles>
</mesh></geometry></library_geometries>
<library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#g"/></node></visual_scene>
</library_visual_scenes><scene><instance_visual_scene url="#s"/></scene></COLLADA>
""")
    assert collada_asset(path) == (0.0254, "y")
    mesh = load_mesh(path)
    expected = {(0.0, 0.0, 0.0), (0.254, 0.0, 0.0), (0.0, 0.0, 0.254)}  # 10 inches; y up -> z up
    assert {tuple(np.round(v, 9) + 0.0) for v in mesh.vertices} == expected


def test_config_checks_and_a_tiny_build(tmp_path):
    fake_sources(tmp_path)
    config = {"family": "real", "family_options": {"sources": sources(tmp_path)}, "seed": 0, "num": 2,
              "splits": {"train": 1.0}, "mesh": {"face_budget": 500, "remesh_resolution": 24},
              "sampling": {"surface": 64, "eval": 64, "sdf": 64, "occ": 64},
              "radar": {"aspect_deg": {"start": 0, "stop": 180, "count": 3},
                        "roll_deg": {"start": 0, "stop": 360, "count": 4, "endpoint": False},
                        "freq_ghz": {"start": 1, "stop": 2, "count": 2}, "size_m": 1.0}}
    path = tmp_path / "real.yaml"
    bad = json.loads(json.dumps(config))
    bad["family_options"]["sources"][0]["up"] = "w"
    path.write_text(yaml.safe_dump(bad))
    with pytest.raises(UserInputError, match=r"sources\[0\]\.up"):
        load_build_config(path)
    path.write_text(yaml.safe_dump(config))
    summary = build_dataset(load_build_config(path), tmp_path / "out", progress=False)
    assert summary.built + summary.skipped == 2 and summary.manifest["classes"] == CLASSES
    assert skip_reason_counts([{"reason": "MeshError: /a/b.ac: no polygon surfaces"},
                               {"reason": "MeshError: /c.ac: no polygon surfaces"}]) == {
        "MeshError: no polygon surfaces": 2}


def _flightgear_root():
    for root in (REPO / "data/real-src", Path("/work/fg/root")):
        if (root / "usr/share/games/flightgear/AI/Aircraft").is_dir():
            return root
    return None


@pytest.mark.skipif(_flightgear_root() is None, reason="FlightGear data not unpacked (make data-real fetches it)")
def test_real_flightgear_tree_splits_aircraft_types_whole():
    root = _flightgear_root()
    family = RealTargetsFamily([{"type": "flightgear_ai", "root": str(root), "up": "y"}])
    tasks = family.plan(None, {"train": 0.8, "val": 0.1, "test": 0.1}, seed=0)
    splits_737 = {t.split for t in tasks if t.source.split("/")[2] in ("733", "734", "735", "736", "738", "739")}
    assert len(splits_737) == 1
    counts = collections.Counter(t.class_name for t in tasks)
    assert counts["airliner"] >= 50 and counts["fighter"] >= 15
    assert not any("/lights/" in t.source.lower() or "flare" in t.source for t in tasks)


def test_variants_are_stretched_training_objects_only(tmp_path):
    fake_sources(tmp_path)
    splits = {"train": 0.5, "val": 0.25, "test": 0.25}
    plain = RealTargetsFamily(sources(tmp_path)).plan(None, splits, seed=3)
    family = RealTargetsFamily(sources(tmp_path), variants={"per_object": 2, "scale": [0.5, 2.0]})
    tasks = family.plan(None, splits, seed=3)
    originals, variants = tasks[:len(plain)], tasks[len(plain):]
    assert originals == plain  # variants leave every original task (id, split, seed) as it was
    train = [t for t in plain if t.split == "train"]
    assert 0 < len(train) < len(plain) and len(variants) == 2 * len(train)
    assert all(v.split == "train" for v in variants) and len({t.record_id for t in tasks}) == len(tasks)
    for v in variants:
        original = next(t for t in train if v.source.startswith(t.source + "#variant"))
        assert (v.class_name, v.label) == (original.class_name, original.label)
        assert v.record_id.startswith(original.record_id + "__v") and v.seed != original.seed
    # A variant is its object stretched, vertex by vertex, by the factors its seed draws.
    variant = variants[0]
    original = family.generate_object(variant.source.split("#variant")[0]).mesh
    stretched = family.generate(variant)
    factors = np.asarray(stretched.provenance["stretch"])
    assert np.all((factors >= 0.5) & (factors <= 2.0)) and np.ptp(factors) > 0.01
    np.testing.assert_allclose(stretched.mesh.vertices, original.vertices * factors, rtol=1e-5, atol=1e-9)
    assert family.generate(variant).provenance["stretch"] == stretched.provenance["stretch"]  # fixed by the seed


@pytest.mark.parametrize("variants, field", [({"per_object": -1}, "per_object"), ({"per_object": 1.5}, "per_object"),
                                             ({"scale": [1.2, 2.0]}, "scale"), ({"scale": [0.0, 1.0]}, "scale"),
                                             ({"scale": 1.2}, "scale"), ({"count": 2}, "unknown key"),
                                             ([1, 2], "expected a mapping")])
def test_bad_variants_name_the_field(tmp_path, variants, field):
    with pytest.raises(UserInputError, match=field):
        RealTargetsFamily(sources(fake_sources(tmp_path)), variants=variants)

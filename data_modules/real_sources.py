"""The ``real`` family: real targets from FlightGear (AC3D) and the Gazebo model database.

Sources (``family_options.sources``, each ``{type, root, up}``):
- ``flightgear_ai``: ``<root>/AI/Aircraft/<type>/**.ac`` (aircraft, a few ships and balloons);
- ``flightgear_models``: ``<root>/Models/**.ac`` except ``Weather/``, ``Effects/``, ``Astro/``
  and ``Autopush/`` (clouds, planets, cursors);
- ``gazebo``: ``<root>/<model>/`` assembled from ``model.sdf`` (``geometry.gazebo``).
``up`` is the source's up axis (AC3D: y; Gazebo: z); meshes are turned into the body frame (z up).

Files that are not objects (lights, flares, exhaust, cockpit switches, stores, deck markings,
empty placeholders) are left out when planning, by the name rules below; every remaining file is
a task, and one that cannot become a watertight solid is skipped with its reason by the builder.

Classes come from explicit tables (``AIRCRAFT`` for the AI aircraft folders, ``MODEL_CLASSES``
for model folders and names, ``GAZEBO_CLASSES``); anything unlisted is ``other``. Splits are by
object, never by file: every file of one object group (all 737 variants and their levels of
detail; the same building under two folders; one Gazebo model) falls in one split, drawn from a
stable hash of ``seed:group``. Identical files (same bytes) are kept once.

Variants (``family_options.variants``, off by default): each training object is also built
``per_object`` more times, stretched along x, y and z by factors drawn log-uniformly from
``scale`` before repair and normalisation, so an airliner stays an airliner with another
length, span and height. Every variant is re-sampled and re-simulated (an anisotropic stretch
does not map an SDF or a radar response onto the stretched object's), and only training objects
get them, so no stretched copy of a validation or test object exists.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np

from radar2shape.errors import UserInputError
from radar2shape.geometry.families.base import Family, Shape, ShapeTask
from radar2shape.geometry.families.folder import sha256_of, stable_unit
from radar2shape.geometry.frames import UP_AXES, to_body_frame

CLASSES = ["airliner", "business jet", "light aircraft", "fighter", "helicopter", "ship", "ground vehicle",
           "building", "household object", "street furniture", "other"]
SOURCE_TYPES = ("flightgear_ai", "flightgear_models", "gazebo")
VARIANT_MARK = "#variant"  # task source of a variant: "<source>#variant<k>"
FG_DATA = "usr/share/games/flightgear"  # below the root of an unpacked flightgear-data-* package

# AI/Aircraft/<folder> -> (object group, class). Groups join the variants of one type (lengths,
# engines, levels of detail), so that no type is in two splits. "fighter" holds every military jet
# and warplane (trainers, bombers, reconnaissance).
AIRCRAFT = {
    **{k: ("737", "airliner") for k in ("733", "734", "735", "736", "738", "739")},
    "717": ("dc9", "airliner"), "MD80": ("dc9", "airliner"), "MD90": ("dc9", "airliner"),
    "727": ("727", "airliner"), "747": ("747", "airliner"), "757": ("757", "airliner"),
    "767": ("767", "airliner"), "777": ("777", "airliner"), "787": ("787", "airliner"),
    "220": ("a220", "airliner"), "A300": ("a300", "airliner"), "A310": ("a300", "airliner"),
    "A319": ("a320", "airliner"), "A320": ("a320", "airliner"), "A321": ("a320", "airliner"),
    "A332": ("a330", "airliner"), "A333": ("a330", "airliner"), "A330-MRTT": ("a330", "airliner"),
    "A342": ("a340", "airliner"), "A343": ("a340", "airliner"), "A345": ("a340", "airliner"),
    "A346": ("a340", "airliner"), "A350": ("a350", "airliner"), "A380": ("a380", "airliner"),
    "AT4": ("atr", "airliner"), "AT7": ("atr", "airliner"), "BAE146-300": ("bae146", "airliner"),
    "Bae146-200": ("bae146", "airliner"), "CR2": ("crj", "airliner"), "CR7": ("crj", "airliner"),
    "CR9": ("crj", "airliner"), "E70": ("ejet", "airliner"), "E90": ("ejet", "airliner"),
    "E95": ("ejet", "airliner"), "ERJ145": ("erj145", "airliner"), "Fokker-70": ("f100", "airliner"),
    "Fokker-100": ("f100", "airliner"), "Fokker-50": ("f50", "airliner"), "JS41": ("js41", "airliner"),
    "SF3": ("saab340", "airliner"), "Saab-2000": ("saab2000", "airliner"), "tu154b": ("tu154", "airliner"),
    "DH3": ("dash8", "airliner"), "DH4": ("dash8", "airliner"), "DH7": ("dash7", "airliner"),
    "b1900d": ("b1900", "airliner"),
    "BAe-125": ("bae125", "business jet"), "Bombardier-Challenger": ("challenger", "business jet"),
    "Citation-Bravo": ("citation", "business jet"), "Embraer-Legacy": ("erj145", "business jet"),
    **{k: (k.lower(), "light aircraft") for k in (
        "Arup-S2", "Beechcraft-Staggerwing", "BNI", "c172", "c177", "Cessna-421-Golden-Eagle", "Cessna208Caravan",
        "Cessna337", "Cub", "DH82", "DR400", "Diamond-Da42", "Dragonfly", "Dromader", "ercoupe", "FK9MK2",
        "Fokker-S-11", "G-164", "M11", "centrair-101", "cri-cri", "flash2a", "pa-28", "DHT", "beech99",
        "beech-200")},
    "c182": ("c182", "light aircraft"), "c182rg": ("c182", "light aircraft"),
    "c310": ("c310", "light aircraft"), "c310u3a": ("c310", "light aircraft"),
    **{k: (k.lower(), "fighter") for k in (
        "339", "A6M2", "Buccaneer", "F-15", "F-18", "F-4", "JA37", "Jaguar-GR1", "Lightning", "MiG-21bis",
        "Mirage2000", "Polikarpov-I16", "SR-71", "Spitfire", "T-38", "bf109", "eurofighter", "f-14b", "f16",
        "seahawk", "vulcanb2")},
    "Ferry": ("ferryboat", "ship"),
}
# Models/<folder>[/<sub>] -> class; the longest matching prefix wins; names below override.
MODEL_CLASSES = {
    "Agriculture": "building", "Buildings": "building", "Commercial": "building", "Industrial": "building",
    "Residential": "building", "Power": "building", "Airport/Jetway": "building",
    "Airport/Pushback": "ground vehicle", "Airport/Vehicle": "ground vehicle", "Airport": "street furniture",
    "Maritime/Civilian": "ship", "Maritime/Military": "ship", "Maritime/Misc": "street furniture",
    "Maritime/Ice": "other", "Military": "ground vehicle", "Transport": "ground vehicle",
    "Aircraft": "other", "Geometry": "other", "Volcanoes": "other",
}
NAME_CLASSES = {  # lower-case file stems
    "f-15-lowpoly": "fighter", "h-60": "helicopter", "dauphin": "helicopter", "tuxcopter": "helicopter",
    "helgovan": "ground vehicle", "supacat_winch": "ground vehicle", "oilrig": "building",
    "pier_25m": "building", "pier_50m": "building", "pier_100m": "building", "pier_200m": "building",
    "yachting-pier-25m": "building", "yachting-pier-50m": "building", "yachting-pier-70m": "building",
    "liferaft4m": "ship", "liferaft8m": "ship", "a4-f-tanker": "fighter", "ka6-d": "fighter",
    "kc135": "airliner", "kc-130": "other", "ferryboat1": "ship", "container_carrier": "ship", "lpd17": "ship",
    "nimitz": "ship", "truman": "ship", "vinson": "ship", "saratoga": "ship", "hull": "ship",
    "sailboat": "ship", "platform": "building", "glider": "light aircraft", "tower1x": "building",
    "towerax": "building", "sunit1x": "building",
    **{f"mule-{n}": "ground vehicle" for n in (11, 12, 14, 21, 22)}, "tracteur": "ground vehicle",
}
MODEL_GROUPS = {  # names of one object under several spellings, or one object's parts
    "cg-57": "ticonderoga", "cg57": "ticonderoga", "cg47": "ticonderoga", "nimitz": "nimitz",
    "truman": "nimitz", "vinson": "nimitz", "lpd17": "lpd17", "maritime-pre-positioning-ship": "mpf",
    "maritimeprepositioningforceship": "mpf", "ferryboat1": "ferryboat", "kc135": "kc135",
    "f-15-lowpoly": "f-15", "hull": "clemenceau", "sailboatunderpower11m": "sailboatunderpower",
}
GAZEBO_CLASSES = {
    **{k: "ground vehicle" for k in ("ambulance", "bus", "hatchback", "pickup", "polaris_ranger_xp900",
                                     "mars_rover", "warehouse_robot")},
    **{k: "building" for k in ("apartment", "cafe", "fast_food", "fire_station", "gas_station", "grocery_store",
                               "house_1", "house_2", "house_3", "law_office", "office_building", "parking_garage",
                               "police_station", "post_office", "powerplant", "reactor", "salon", "school",
                               "thrift_shop", "water_tower", "radio_tower", "gazebo", "pier")},
    **{k: "street furniture" for k in ("bus_stop", "construction_barrel", "construction_cone", "dumpster",
                                       "fire_hydrant", "first_2015_trash_can", "fountain", "jersey_barrier",
                                       "lamp_post", "mailbox", "postbox", "speed_limit_sign", "stop_light",
                                       "stop_sign", "telephone_pole", "standpipe", "playground")},
    **{k: "household object" for k in ("bowl", "cafe_table", "cardboard_box", "coke_can", "cordless_drill",
                                       "door_handle", "grey_tote", "hammer", "monkey_wrench", "plastic_cup",
                                       "saucepan", "table_marble", "euro_pallet", "cinder_block", "car_wheel")},
    "cessna": "light aircraft",
}
GAZEBO_GROUPS = {"cessna": "c172"}  # the Gazebo Cessna 172 is the FlightGear c172 type
# Files that are not objects: light cones and flares, exhaust, switches, stores and tanks, props
# and wheels split off a model, deck markings and lighting layers, placeholders, scenery.
NOT_OBJECT = re.compile(
    r"(^|[-_ ])(light|lights|flare|flash|strobe|beacon|nav[lrb]?|toggle|exhaust|banner|bomb|droptank|tank|wheels|"
    r"probe|refueling|ssme|omspods|cone|^glass|cursor|waypoint|clouds?|earth|aurora|contrail|puff|tracer2?|crater|"
    r"null|square|thermalcap|load|sillage|cut|datum|flols|glide-path|wave-off|clock|ensign|foxtrot|golf|parks|"
    r"rembrandt|groundtile|towropes|testpilot|parachuter|aim91x|mk82|rocket|rp-3|rp-3-25|impact|propeller|"
    r"kilauea|phalanx|sea-sparrow|deck-crane|grue_pont|pont-v2|clem-superstructure|superstructure|whitelight1?|"
    r"redlight|greenlight|landinglights|drop-line|procedural_light|warning-light|ils)($|[-_ .])",
    re.IGNORECASE)
NOT_OBJECT_FOLDERS = {"lights", "light", "propellers", "refueling", "weather", "effects", "astro", "autopush"}


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-")


def normalised_stem(stem: str) -> str:
    """A model name without colour, level-of-detail and numbering variants (one object group)."""
    name = stem.lower()
    if name in MODEL_GROUPS:
        return MODEL_GROUPS[name]
    name = re.sub(r"(_|-)?(low-?poly|hi-?res|high-detail|ba|ai)$", "", name)
    name = re.sub(r"[-_]?(white|grey|gray|green|yellow|red|blue|black|dark|striped|tile)", "", name)
    name = re.sub(r"[-_ ]?\d+$", "", name)
    return name or stem.lower()


def not_object(relative: str) -> str | None:
    """Why a file is not an object (None when it is one)."""
    parts = Path(relative).parts
    folders = {p.lower() for p in parts[:-1]}
    if folders & NOT_OBJECT_FOLDERS:
        return f"folder {sorted(folders & NOT_OBJECT_FOLDERS)[0]}/"
    stem = Path(relative).stem
    if NOT_OBJECT.search(stem):
        return "name (light, flare, store, marking or scenery part)"
    return None


def model_class(relative: str) -> str:
    """Class of a ``Models/...`` file: the name table, else the longest folder prefix, else other."""
    stem = Path(relative).stem.lower()
    if stem in NAME_CLASSES:
        return NAME_CLASSES[stem]
    folders = Path(relative).parts[1:-1]
    for depth in range(len(folders), 0, -1):
        key = "/".join(folders[:depth])
        if key in MODEL_CLASSES:
            return MODEL_CLASSES[key]
    return "other"


class RealTargetsFamily(Family):
    """Real targets from several sources, one task per object file (Gazebo: per model folder)."""

    name = "real"

    def __init__(self, sources: list, val_fraction: float = 0.1, variants: dict | None = None):
        if not isinstance(sources, (list, tuple)) or not sources:
            raise UserInputError("real.sources: expected a list of {type, root, up} entries")
        self.sources = []
        for number, source in enumerate(sources):
            if not isinstance(source, dict) or set(source) - {"type", "root", "up"} or "root" not in source:
                raise UserInputError(f"real.sources[{number}]: expected keys type, root, up; got {source!r}")
            kind, up = source.get("type"), str(source.get("up", "z"))
            if kind not in SOURCE_TYPES:
                raise UserInputError(f"real.sources[{number}].type: expected one of {', '.join(SOURCE_TYPES)}, "
                                     f"got {kind!r}")
            if up.lower() not in UP_AXES:
                raise UserInputError(f"real.sources[{number}].up: expected one of {', '.join(UP_AXES)}, got {up!r}")
            root = Path(str(source["root"])).expanduser()
            if not root.is_dir():
                raise UserInputError(f"real.sources[{number}].root: {root} is not a directory "
                                     "(`make data-real` fetches the FlightGear packages)")
            self.sources.append({"type": kind, "root": root, "up": up.lower()})
        self.val_fraction = val_fraction
        self.variants = _checked_variants(variants)
        self.class_names = list(CLASSES)
        self.excluded: list[tuple[str, str]] = []  # (source path, why), filled by ``objects``

    def _fg_base(self, root: Path) -> Path:
        return root / FG_DATA if (root / FG_DATA).is_dir() else root

    def objects(self) -> list[dict]:
        """Every object file: ``{source, path, group, class, up}``, in a fixed order, duplicates dropped."""
        found, self.excluded = [], []
        for number, source in enumerate(self.sources):
            root, kind = source["root"], source["type"]
            if kind == "gazebo":
                for model in sorted(p for p in root.iterdir() if p.is_dir()):
                    found.append({"source": f"{number}:{model.name}", "path": model, "up": source["up"],
                                  "group": GAZEBO_GROUPS.get(model.name, f"gazebo-{model.name}"),
                                  "class": GAZEBO_CLASSES.get(model.name, "other")})
                continue
            base = self._fg_base(root)
            pattern = "AI/Aircraft/*/**/*.ac" if kind == "flightgear_ai" else "Models/**/*.ac"
            for path in sorted(base.glob(pattern)):
                relative = path.relative_to(base).as_posix()
                reason = not_object(relative)
                if reason:
                    self.excluded.append((relative, reason))
                    continue
                if kind == "flightgear_ai":
                    folder = Path(relative).parts[2]
                    group, class_name = AIRCRAFT.get(folder, (folder.lower(), "other"))
                else:
                    group, class_name = normalised_stem(path.stem), model_class(relative)
                found.append({"source": f"{number}:{relative}", "path": path, "up": source["up"],
                              "group": group, "class": class_name})
        unique, seen = [], {}
        for item in found:  # the same file shipped under two folders is one object
            if item["path"].is_file():
                digest = sha256_of(item["path"])
                if digest in seen:
                    self.excluded.append((item["source"], f"same file as {seen[digest]}"))
                    continue
                seen[digest] = item["source"]
            unique.append(item)
        return unique

    def split_of(self, group: str, splits: dict[str, float], seed: int) -> str:
        """The split of an object group: a stable hash of ``seed:group`` against the split fractions."""
        edges = np.cumsum(list(splits.values())) / sum(splits.values())
        return list(splits)[int(np.searchsorted(edges, stable_unit(f"{seed}:{group}"), side="right"))]

    def plan(self, num, splits, seed):
        items = self.objects()
        if num is not None and num < len(items):
            keep = sorted(items, key=lambda i: stable_unit(f"{seed}:{i['source']}"))[:num]
            items = [i for i in items if i in keep]
        tasks = []
        for item in items:
            name = Path(item["source"].split(":", 1)[1]).with_suffix("").name
            record_id = _slug(f"{item['class'].replace(' ', '-')}__{item['group']}__{name}")
            tasks.append(ShapeTask(self.split_of(item["group"], splits, seed), record_id,
                                   CLASSES.index(item["class"]), item["class"],
                                   int(stable_unit(f"{seed}:{item['source']}") * 2**32), source=item["source"]))
        tasks += [variant_task(t, k) for t in tasks if t.split == "train"
                  for k in range(1, self.variants["per_object"] + 1)]
        ids = [t.record_id for t in tasks]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:  # two files of one group with one name: keep ids unique with a short hash
            tasks = [t if t.record_id not in duplicates else
                     ShapeTask(t.split, f"{t.record_id}-{hashlib.sha1(t.source.encode()).hexdigest()[:6]}",
                               t.label, t.class_name, t.seed, t.source) for t in tasks]
        return tasks

    def generate(self, task: ShapeTask) -> Shape:
        source_id, _, variant = task.source.partition(VARIANT_MARK)
        shape = self.generate_object(source_id)
        if not variant:
            return shape
        factors = self.stretch_factors(task.seed)
        mesh = shape.mesh.copy()
        mesh.apply_scale(factors)
        return Shape(mesh, {**shape.provenance, "variant": int(variant), "stretch": factors.round(6).tolist()})

    def stretch_factors(self, seed: int) -> np.ndarray:
        """The x, y, z stretch of a variant: log-uniform in ``variants.scale``, fixed by its seed."""
        low, high = np.log(self.variants["scale"])
        return np.exp(np.random.default_rng(seed).uniform(low, high, size=3))

    def generate_object(self, source_id: str) -> Shape:
        """The object of one source entry (``"<source number>:<relative path>"``) in the body frame."""
        number, relative = source_id.split(":", 1)
        source = self.sources[int(number)]
        if source["type"] == "gazebo":
            from radar2shape.geometry.gazebo import load_gazebo_model

            path = source["root"] / relative
            mesh, report = load_gazebo_model(path)
            provenance = {"parts": report["parts"], "missing_parts": report["missing"],
                          "centred_submeshes_left_out": report["centred_submesh"]}
        else:
            from radar2shape.geometry.ac3d import read_ac3d

            path = self._fg_base(source["root"]) / relative
            mesh = read_ac3d(path)
            provenance = {"ac3d_skipped": mesh.metadata["ac3d_skipped"], "sha256": sha256_of(path)}
        body = to_body_frame(mesh, source["up"])
        return Shape(body, {"generator": self.name, "source": f"{source['type']}:{relative}", "up": source["up"],
                            **provenance})


def _checked_variants(variants: dict | None) -> dict:
    """``variants`` with its defaults, or a UserInputError naming the bad field."""
    if variants is not None and not isinstance(variants, dict):
        raise UserInputError(f"real.variants: expected a mapping {{per_object, scale}}, got {variants!r}")
    merged = {"per_object": 0, "scale": [0.8, 1.25], **(variants or {})}
    unknown = sorted(set(merged) - {"per_object", "scale"})
    if unknown:
        raise UserInputError(f"real.variants: unknown key(s) {unknown}; expected per_object, scale")
    count, scale = merged["per_object"], merged["scale"]
    if isinstance(count, bool) or not isinstance(count, int) or count < 0:
        raise UserInputError(f"real.variants.per_object: expected a whole number >= 0, got {count!r}")
    if (not isinstance(scale, (list, tuple)) or len(scale) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in scale)
            or not 0 < scale[0] <= 1 <= scale[1]):
        raise UserInputError(f"real.variants.scale: expected [low, high] with 0 < low <= 1 <= high, got {scale!r}")
    return {"per_object": count, "scale": [float(scale[0]), float(scale[1])]}


def variant_task(task: ShapeTask, k: int) -> ShapeTask:
    """The ``k``-th stretched variant of ``task``: same split, class and group, its own id and seed."""
    source = f"{task.source}{VARIANT_MARK}{k}"
    return ShapeTask(task.split, f"{task.record_id}__v{k}", task.label, task.class_name,
                     int(stable_unit(f"{task.seed}{VARIANT_MARK}{k}") * 2**32), source=source)


def skip_reason_counts(skipped: list[dict]) -> dict[str, int]:
    """Skips counted by reason, with paths and numbers taken out so that like reasons add up."""
    counts: dict[str, int] = {}
    for entry in skipped:
        reason = re.sub(r"\S*/\S*:?\s*", "", entry.get("reason", ""))
        reason = re.sub(r"\d[\d.,e+-]*", "N", reason).strip()
        counts[reason] = counts.get(reason, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: -kv[1]))

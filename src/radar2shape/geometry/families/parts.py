"""The ``parts`` family: composite objects of ten classes, built from primitives with exact unions.

Classes come in confusable groups that share a coarse shape and differ in fine parts, as
ModelNet classes do: chair / stool / table (legs under a top), bottle / mug / vase (a vertical
body of revolution), airplane / rocket (a slender fuselage), lamp, car. Each class has
structural variants (legs or pedestal, arms, engines, fins, handles, ...) and continuous random
parameters; ``build_part(class_name, rng)`` returns the solid and the variant it drew.
Model units: z up, about one unit across; the builder normalises afterwards.
"""

from __future__ import annotations

from collections.abc import Callable

import manifold3d as m3
import numpy as np

from radar2shape.geometry.manifold import to_trimesh

from radar2shape.errors import UserInputError
from radar2shape.geometry.families.base import Family, Shape, ShapeTask, procedural_tasks
from radar2shape.geometry.families.primitives import (
    box,
    cylinder,
    plate,
    revolved,
    ring_positions,
    sphere,
    torus,
    union,
)

Builder = Callable[[np.random.Generator, int], tuple[m3.Manifold, dict]]


def _legs(rng, kind: str, width: float, depth: float, height: float, thick: float, seg: int) -> list[m3.Manifold]:
    """Supports under a top of ``width`` x ``depth`` whose underside is at ``height``."""
    if kind == "four":
        inset = 0.9 * thick
        xs, ys = (width / 2 - inset) * np.array([-1, 1]), (depth / 2 - inset) * np.array([-1, 1])
        round_legs = rng.random() < 0.5
        return [
            cylinder(thick / 2, height + 0.02, (x, y, height / 2), segments=seg)
            if round_legs else box((thick, thick, height + 0.02), (x, y, height / 2))
            for x in xs for y in ys
        ]
    if kind == "pedestal":
        spokes = int(rng.integers(4, 6))
        foot = 0.45 * min(width, depth)
        stem = [cylinder(thick * 0.7, height + 0.02, (0, 0, height / 2), segments=seg)]
        return stem + [
            box((foot, thick, thick), (0, 0, thick / 2)).translate([foot / 2, 0, 0]).rotate([0, 0, 360 * k / spokes])
            for k in range(spokes)
        ]
    # "panels": two slab sides (trestle)
    return [box((thick, depth * 0.8, height + 0.02), (x, 0, height / 2)) for x in (-width / 2 + thick, width / 2 - thick)]


def chair(rng, seg):
    w, d, h = rng.uniform(0.4, 0.55), rng.uniform(0.4, 0.55), rng.uniform(0.4, 0.5)
    t = rng.uniform(0.04, 0.06)
    variant = {"legs": str(rng.choice(["four", "pedestal"])), "arms": bool(rng.random() < 0.4),
               "back": str(rng.choice(["solid", "slats"]))}
    back_h = rng.uniform(0.35, 0.55)
    parts = [box((w, d, t), (0, 0, h + t / 2))] + _legs(rng, variant["legs"], w, d, h, t, seg)
    back_y, back_top = -d / 2 + t / 2, h + t + back_h
    if variant["back"] == "solid":
        parts.append(box((w, t, back_h + t), (0, back_y, h + t / 2 + back_h / 2)))
    else:
        slats = int(rng.integers(2, 5))
        parts += [box((t * 0.8, t, back_h + t), (x, back_y, h + t / 2 + back_h / 2)) for x in np.linspace(-w / 2 + t, w / 2 - t, slats)]
        parts.append(box((w, t, 2 * t), (0, back_y, back_top - t)))
    if variant["arms"]:
        arm_h = rng.uniform(0.18, 0.25)
        parts += [box((t, d * 0.9, t), (x, 0, h + t + arm_h)) for x in (-w / 2 + t / 2, w / 2 - t / 2)]
        parts += [box((t, t, arm_h + t), (x, d * 0.35, h + t / 2 + arm_h / 2)) for x in (-w / 2 + t / 2, w / 2 - t / 2)]
    return union(*parts), variant


def stool(rng, seg):
    h, r, t = rng.uniform(0.45, 0.75), rng.uniform(0.15, 0.22), rng.uniform(0.04, 0.06)
    variant = {"legs": int(rng.choice([3, 4])), "seat": str(rng.choice(["round", "square"])),
               "footring": bool(rng.random() < 0.5)}
    seat = cylinder(r, t, (0, 0, h + t / 2), segments=seg) if variant["seat"] == "round" else box((2 * r, 2 * r, t), (0, 0, h + t / 2))
    legs = [cylinder(t / 2, h + 0.02, p, segments=seg) for p in ring_positions(variant["legs"], 0.75 * r, h / 2, np.pi / 4)]
    parts = [seat] + legs
    if variant["footring"]:
        parts.append(torus(0.75 * r, t / 3, (0, 0, 0.35 * h), segments=seg))
    return union(*parts), variant


def table(rng, seg):
    w, d, h = rng.uniform(0.8, 1.4), rng.uniform(0.5, 0.9), rng.uniform(0.6, 0.75)
    t = rng.uniform(0.03, 0.06)
    variant = {"legs": str(rng.choice(["four", "pedestal", "panels"])), "top": str(rng.choice(["rect", "round"]))}
    if variant["top"] == "round":
        w = d = max(w, d) * 0.8
        top = cylinder(w / 2, t, (0, 0, h + t / 2), segments=seg)
    else:
        top = box((w, d, t), (0, 0, h + t / 2))
    inner = w / np.sqrt(2) if variant["top"] == "round" else w
    return union(top, *_legs(rng, variant["legs"], inner, d if variant["top"] == "rect" else inner, h, 2 * t, seg)), variant


def airplane(rng, seg):
    length, r = 1.0, rng.uniform(0.04, 0.07)
    span, chord = rng.uniform(0.8, 1.1), rng.uniform(0.12, 0.2)
    sweep = rng.uniform(0.0, 0.25)
    variant = {"engines": int(rng.choice([0, 2, 4])), "tail": str(rng.choice(["conventional", "t-tail"])),
               "swept": bool(sweep > 0.1)}
    body = cylinder(r, 0.7 * length, (0, 0, 0), axis="x", segments=seg)
    nose = cylinder(r, 0.15, (0.425, 0, 0), axis="x", radius_top=r * 0.2, segments=seg)
    tail = cylinder(r * 0.4, 0.15, (-0.425, 0, r * 0.3), axis="x", radius_top=r, segments=seg)
    half = span / 2
    wing = plate(np.array([[chord / 2, 0], [chord / 2 - sweep, half], [-chord / 2 - sweep, half], [-chord / 2, 0]]), r * 0.3)
    wings = union(wing, wing.mirror([0, 1, 0]))
    fin_h = rng.uniform(0.12, 0.2)
    fin = plate(np.array([[-0.5, 0], [-0.38, 0], [-0.47, fin_h], [-0.5, fin_h]]) + [0, r * 0.5], r * 0.25, "xz")
    stab_z = r * 0.5 + fin_h if variant["tail"] == "t-tail" else 0.0
    stab = plate(np.array([[-0.5, -0.15], [-0.4, -0.15], [-0.4, 0.15], [-0.5, 0.15]]), r * 0.25).translate([0, 0, stab_z])
    parts = [body, nose, tail, wings, fin, stab]
    for k in range(variant["engines"]):
        y = (0.25 + 0.2 * (k // 2)) * half * (1 if k % 2 else -1)
        parts.append(cylinder(r * 0.5, chord * 0.9, (chord * 0.2 - sweep * abs(y) / half, y, -r * 0.6), axis="x", segments=seg))
        parts.append(box((chord * 0.3, r * 0.2, r * 0.6), (-sweep * abs(y) / half, y, -r * 0.3)))
    return union(*parts), variant


def rocket(rng, seg):
    h, r = 1.0, rng.uniform(0.05, 0.09)
    variant = {"fins": int(rng.choice([3, 4])), "boosters": int(rng.choice([0, 2, 4])), "nozzle": bool(rng.random() < 0.6)}
    nose_h = rng.uniform(0.15, 0.3)
    body_h = h - nose_h
    parts = [cylinder(r, body_h, (0, 0, body_h / 2), segments=seg),
             cylinder(r, nose_h, (0, 0, body_h + nose_h / 2 - 0.001), radius_top=0.0, segments=seg)]
    fin_h, fin_w = rng.uniform(0.12, 0.25), rng.uniform(0.06, 0.12)
    fin = plate(np.array([[r * 0.5, 0], [r + fin_w, 0], [r + fin_w, fin_h * 0.3], [r * 0.5, fin_h]]), r * 0.25, "xz")
    parts += [fin.rotate([0, 0, 360 * k / variant["fins"]]) for k in range(variant["fins"])]
    for p in ring_positions(variant["boosters"], r * 1.3, 0.0, np.pi / 4):
        bh = body_h * 0.45
        parts.append(cylinder(r * 0.45, bh, (p[0], p[1], bh / 2 + 0.02), segments=seg))
        parts.append(cylinder(r * 0.45, 0.08, (p[0], p[1], bh + 0.055), radius_top=0.0, segments=seg))
    if variant["nozzle"]:
        parts.append(cylinder(r * 0.7, 0.06, (0, 0, -0.025), radius_top=r * 0.4, segments=seg))
    return union(*parts), variant


def lamp(rng, seg):
    variant = {"base": str(rng.choice(["disk", "square"])), "arm": bool(rng.random() < 0.5),
               "shade": str(rng.choice(["cone", "globe"]))}
    base_r, pole_h = rng.uniform(0.12, 0.2), rng.uniform(0.5, 0.8)
    base = cylinder(base_r, 0.04, (0, 0, 0.02), segments=seg) if variant["base"] == "disk" else box((2 * base_r, 2 * base_r, 0.04), (0, 0, 0.02))
    pole_r = rng.uniform(0.012, 0.02)
    parts = [base, cylinder(pole_r, pole_h, (0, 0, pole_h / 2 + 0.02), segments=seg)]
    top = np.array([0.0, 0.0, pole_h])
    if variant["arm"]:
        arm = rng.uniform(0.15, 0.3)
        parts.append(cylinder(pole_r, arm, (arm / 2 - pole_r, 0, pole_h), axis="x", segments=seg))
        parts.append(sphere(pole_r * 1.5, top, segments=seg))
        top = top + [arm - 2 * pole_r, 0, 0]
    shade_r = rng.uniform(0.1, 0.18)
    if variant["shade"] == "cone":
        parts.append(cylinder(shade_r, shade_r, top - [0, 0, shade_r * 0.4], radius_top=shade_r * 0.5, segments=seg))
    else:
        parts.append(sphere(shade_r * 0.8, top - [0, 0, shade_r * 0.5], segments=seg))
    return union(*parts), variant


def bottle(rng, seg):
    variant = {"body": str(rng.choice(["round", "square"])), "cap": bool(rng.random() < 0.6),
               "neck": str(rng.choice(["short", "long"]))}
    r, body_h = rng.uniform(0.12, 0.2), rng.uniform(0.45, 0.65)
    neck_r = r * rng.uniform(0.25, 0.4)
    neck_h = rng.uniform(0.08, 0.12) if variant["neck"] == "short" else rng.uniform(0.18, 0.28)
    shoulder_h = rng.uniform(0.08, 0.15)
    body = cylinder(r, body_h, (0, 0, body_h / 2), segments=seg) if variant["body"] == "round" else box((2 * r, 2 * r, body_h), (0, 0, body_h / 2))
    shoulder = cylinder(r * (1.0 if variant["body"] == "round" else 1.2), shoulder_h, (0, 0, body_h + shoulder_h / 2 - 0.005),
                        radius_top=neck_r, segments=seg)
    if variant["body"] == "square":
        shoulder = shoulder ^ box((2 * r, 2 * r, shoulder_h), (0, 0, body_h + shoulder_h / 2 - 0.005))
    neck_z = body_h + shoulder_h
    parts = [body, shoulder, cylinder(neck_r, neck_h + 0.01, (0, 0, neck_z + neck_h / 2 - 0.005), segments=seg)]
    if variant["cap"]:
        parts.append(cylinder(neck_r * 1.25, 0.04, (0, 0, neck_z + neck_h), segments=seg))
    return union(*parts), variant


def mug(rng, seg):
    variant = {"handle": str(rng.choice(["round", "square"])), "saucer": bool(rng.random() < 0.3)}
    r, h, wall = rng.uniform(0.15, 0.25), rng.uniform(0.25, 0.45), rng.uniform(0.015, 0.03)
    body = cylinder(r, h, (0, 0, h / 2), segments=seg) - cylinder(r - wall, h, (0, 0, h / 2 + wall), segments=seg)
    handle_r, tube = h * rng.uniform(0.25, 0.35), wall * 1.2
    if variant["handle"] == "round":
        handle = torus(handle_r, tube, (r, 0, h / 2), rotate=(90, 0, 0), segments=seg)
    else:
        handle = box((handle_r * 1.5, tube * 2, handle_r * 2), (r + handle_r * 0.5, 0, h / 2)) - box(
            (handle_r * 1.5 - 2 * tube, tube * 4, handle_r * 2 - 2 * tube * 2), (r + handle_r * 0.5, 0, h / 2))
    handle = handle - cylinder(r - wall / 2, h, (0, 0, h / 2), segments=seg)
    parts = [body, handle]
    if variant["saucer"]:
        parts.append(cylinder(r * 1.6, 0.02, (0, 0, 0.0), segments=seg))
    return union(*parts), variant


def vase(rng, seg):
    variant = {"handles": int(rng.choice([0, 2])), "open": bool(rng.random() < 0.7)}
    h = rng.uniform(0.6, 1.0)
    z = np.linspace(0.0, h, 12)
    waves = rng.uniform(0.5, 1.5)
    r = rng.uniform(0.12, 0.2) * (1 + 0.35 * np.sin(2 * np.pi * waves * z / h + rng.uniform(0, np.pi)))
    outline = np.vstack([[0.0, 0.0], np.stack([r, z], axis=1), [0.0, h]])
    solid = revolved(outline, seg)
    if variant["open"]:
        solid = solid - cylinder(0.7 * r[z > 0.65 * h].min(), h * 0.3, (0, 0, h * 0.86), segments=seg)
    parts = [solid]
    for side in (1, -1)[: variant["handles"]]:
        parts.append(torus(h * 0.12, 0.015, (side * r[8], 0, z[8]), rotate=(90, 0, 0), segments=seg))
    return union(*parts), variant


def car(rng, seg):
    variant = {"body": str(rng.choice(["sedan", "pickup", "van"])), "spoiler": bool(rng.random() < 0.3)}
    length, width, ride = 1.0, rng.uniform(0.38, 0.48), rng.uniform(0.07, 0.1)
    body_h = rng.uniform(0.12, 0.18)
    wheel_r = rng.uniform(0.07, 0.1)
    parts = [box((length, width, body_h), (0, 0, ride + body_h / 2))]
    top = ride + body_h - 0.005
    cab_h = rng.uniform(0.12, 0.18) * (1.5 if variant["body"] == "van" else 1.0)
    span = {"sedan": (-0.25, 0.2), "pickup": (-0.05, 0.3), "van": (-0.48, 0.25)}[variant["body"]]
    a, b = span
    cabin = plate(np.array([[a, top], [b + 0.1, top], [b - 0.02, top + cab_h], [a + 0.06, top + cab_h]]), width * 0.9, "xz")
    parts.append(cabin)
    for x in (-0.32, 0.32):
        for y in (-width / 2, width / 2):
            parts.append(cylinder(wheel_r, 0.07, (x, y, wheel_r), axis="y", segments=seg))
    if variant["spoiler"]:
        parts.append(box((0.06, width * 0.9, 0.015), (-0.47, 0, top + 0.07)))
        parts += [box((0.02, 0.02, 0.08), (-0.47, y, top + 0.03)) for y in (-width * 0.3, width * 0.3)]
    solid = union(*parts)
    if variant["body"] == "pickup":
        solid = solid - box((0.4, width * 0.8, body_h), (-0.27, 0, top + body_h / 2 - 0.06))
    return solid, variant


PART_CLASSES: dict[str, Builder] = {
    "airplane": airplane, "bottle": bottle, "car": car, "chair": chair, "lamp": lamp,
    "mug": mug, "rocket": rocket, "stool": stool, "table": table, "vase": vase,
}


def build_part(class_name: str, rng: np.random.Generator, segments: int = 24) -> tuple[m3.Manifold, dict]:
    """A random solid of ``class_name`` and the structural variant it drew."""
    return PART_CLASSES[class_name](rng, segments)


class PartsFamily(Family):
    """Composite objects of the classes in ``PART_CLASSES`` (or a subset), balanced per split."""

    name = "parts"

    def __init__(self, classes: list[str] | None = None, segments: int = 24):
        unknown = sorted(set(classes or []) - set(PART_CLASSES))
        if unknown:
            raise UserInputError(f"parts.classes: unknown class(es) {unknown}; choose from {sorted(PART_CLASSES)}")
        self.class_names = sorted(classes or PART_CLASSES)
        self.segments = segments

    def plan(self, num, splits, seed):
        return procedural_tasks(num, splits, seed, self.class_names)

    def generate(self, task: ShapeTask) -> Shape:
        solid, variant = build_part(task.class_name, np.random.default_rng(task.seed), self.segments)
        return Shape(to_trimesh(solid), {"generator": self.name, "seed": task.seed, "variant": variant})

"""The two bundled personalities: their shapes, looks, ways of speaking and of showing feelings,
and their habits in time.

``cybatt`` is the calm one: an oval face, slow smooth smiles that show the teeth, a blink every
four seconds. ``lotta`` is the lively one: a broader jaw, longer nose, higher brows and wider-set
eyes (Candide-3 shape units), a lopsided grin, brows that join every feeling, quick blinks and
nods.

A recipe (viseme or expression) is what the modeler dials in: low-level FAP values (in FAP
units, through the head's own FAP deformations) and Candide's regional animation units (in
Candide's units).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Look:
    """Colours (RGB 0–255) and the texture's random seed."""

    seed: int
    skin: tuple[float, float, float]
    blush: tuple[float, float, float]
    lid: tuple[float, float, float]
    lash: tuple[float, float, float]
    brow: tuple[float, float, float]
    lips: tuple[float, float, float]
    hair: tuple[float, float, float]
    iris: tuple[float, float, float]
    teeth: tuple[float, float, float] = (236, 230, 212)


@dataclass
class Recipe:
    faps: dict[int, float] = field(default_factory=dict)
    au: dict[str, float] = field(default_factory=dict)


@dataclass
class Personality:
    name: str
    title: str
    look: Look
    shape_units: dict[str, float] = field(default_factory=dict)
    tweaks: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    # eyes
    eye_radius: float = 0.15
    eye_shift: tuple[float, float] = (0.0, 0.0)
    eye_depth: float = 0.02
    pupil_angle: float = 0.16
    iris_angle: float = 0.42
    lid_push: float = 0.03
    # skull, neck, ears
    skull_centre: tuple[float, float, float] = (0.0, 0.28, -0.78)
    skull_axes: tuple[float, float, float] = (0.78, 1.12, 1.02)
    cap_rings: int = 14
    neck_bottom: float = -1.35
    neck_top: float = -0.55
    neck_radii: tuple[float, float] = (0.34, 0.34)
    neck_centre_z: float = -0.8
    ear_size: tuple[float, float, float] = (0.29, 0.17, 0.06)
    ear_angle: float = 0.35
    ear_centre: tuple[float, float, float] = (0.79, 0.07, -0.84)
    hairline_front: float = 0.84
    hairline_temple: float = 0.6
    hairline_nape: float = -0.45
    # mouth
    teeth_gap: float = 0.035
    arch_depth: float = 0.16
    teeth_show: float = 0.01
    tongue_size: tuple[float, float, float] = (0.15, 0.11, 0.035)
    jaw_pivot: tuple[float, float, float] = (0.0, 0.02, -0.68)
    jaw_glide: float = 0.25
    head_pivot: tuple[float, float, float] = (0.0, -0.8, -0.7)
    # behaviour
    visemes: dict[int, Recipe] = field(default_factory=dict)
    expressions: dict[str, Recipe] = field(default_factory=dict)
    temporal: list[str] = field(default_factory=list)

    def hairline(self, abs_theta: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """Height of the hairline over the angle about the skull's axis (0 = the front)."""
        a = np.asarray(abs_theta)
        f, t, nape = self.hairline_front, self.hairline_temple, self.hairline_nape
        ear_top = self.ear_centre[1] + self.ear_size[0] + 0.03
        # forehead, temples, a sideburn in front of the ear, over the ear, down to the nape
        angles = [0.0, 0.45, 0.85, 1.1, 1.28, 1.38, 1.46, 1.84, 2.15, np.pi]
        heights = [f, f - 0.03, f - 0.1, t, t - 0.15, 0.02, ear_top, ear_top, nape, nape]
        y = np.interp(a, angles, heights)
        return y


# ---- visemes and expressions -------------------------------------------------------------------

#: Lips together and pressed (Candide's lip presser), as in p, b, m.
PRESSED = {"Lip presser": 0.8}


def cybatt_visemes() -> dict[int, Recipe]:
    return {
        1: Recipe({16: -70, 17: -60, 4: 15, 5: 15}, PRESSED),
        2: Recipe({3: 110, 5: 150, 10: 120, 11: 120, 16: -100, 4: -110, 8: -70, 9: -70}),
        3: Recipe({3: 230, 45: 170, 44: 330, 4: -70, 6: 60, 7: 60}),
        4: Recipe({3: 200, 44: 420, 45: 60, 6: 80, 7: 80, 4: -60}),
        5: Recipe({3: 260, 46: 300, 6: 60, 7: 60}),
        6: Recipe({3: 150, 16: 240, 17: 220, 6: -100, 7: -100, 53: -80, 54: -80, 4: -60,
                   5: -60}),
        7: Recipe({3: 70, 6: 170, 7: 170, 53: 120, 54: 120, 4: -110, 5: -130, 8: -60, 9: -60}),
        8: Recipe({3: 220, 44: 360, 6: 60, 7: 60, 4: -40}),
        9: Recipe({3: 180, 16: 150, 17: 140, 6: -80, 7: -80, 4: -40}),
        10: Recipe({3: 700, 6: 60, 7: 60, 4: -120, 8: -90, 9: -90}),
        11: Recipe({3: 380, 6: 190, 7: 190, 53: 120, 54: 120, 4: -100}),
        12: Recipe({3: 220, 6: 260, 7: 260, 53: 180, 54: 180, 12: 60, 13: 60, 4: -90}),
        13: Recipe({3: 540, 6: -90, 7: -90, 16: 120, 17: 120, 4: -60}),
        14: Recipe({3: 200, 6: -150, 7: -150, 53: -110, 54: -110, 16: 300, 17: 280}),
    }  # fmt: skip


def cybatt_expressions() -> dict[str, Recipe]:
    return {
        "joy": Recipe(
            {12: 360, 13: 360, 59: 320, 60: 320, 6: 200, 7: 200, 53: 180, 54: 180, 41: 460,
             42: 460, 21: 200, 22: 200, 4: -150, 3: 90, 5: -40, 33: 60, 34: 60}
        ),
        "sadness": Recipe(
            {31: 220, 32: 220, 33: -40, 34: -40, 35: -90, 36: -90, 37: 40, 38: 40, 12: -180,
             13: -180, 59: -170, 60: -170, 19: 260, 20: 260, 18: 90, 5: 40},
        ),
        "anger": Recipe(
            {37: 140, 38: 140, 31: -120, 32: -120, 33: -90, 34: -90, 35: -30, 36: -30, 19: 120,
             20: 120, 21: 240, 22: 240, 5: 60, 4: 30, 61: 60, 62: 60},
            {"Brow lowerer": 0.7, "Lip presser": 0.6, "Lid tightener": 0.3},
        ),
        "fear": Recipe(
            {31: 320, 32: 320, 33: 160, 34: 160, 35: 60, 36: 60, 37: 80, 38: 80, 19: -260,
             20: -260, 3: 200, 6: 180, 7: 180, 53: 160, 54: 160, 5: -90},
        ),
        "disgust": Recipe(
            {4: -40, 12: -60, 13: -30, 31: -80, 32: -80, 21: 260, 22: 260, 63: 120, 61: 90,
             62: 90, 16: 80, 3: 40},
            {"Nose wrinkler": 0.5, "Upper lip raiser": 0.3},
        ),
        "surprise": Recipe(
            {31: 380, 32: 380, 33: 420, 34: 420, 35: 360, 36: 360, 19: -330, 20: -330, 21: -60,
             22: -60, 3: 520, 6: -60, 7: -60, 4: -60},
        ),
    }  # fmt: skip


CYBATT = Personality(
    name="cybatt",
    title="cybatt — the calm one",
    look=Look(
        seed=1999,
        skin=(224, 178, 150),
        blush=(214, 128, 118),
        lid=(196, 146, 132),
        lash=(48, 34, 30),
        brow=(78, 56, 42),
        lips=(186, 104, 100),
        hair=(92, 62, 40),
        iris=(70, 110, 150),
    ),
    shape_units={"Eyes height": 0.35, "Mouth lip thickness": 0.5, "Nose lower z-extension": 0.15},
    visemes=cybatt_visemes(),
    expressions=cybatt_expressions(),
    temporal=[
        "expression joy: onset 0.7 offset 0.9 shape smooth climax 1 duration 2.5",
        "expression sadness: onset 1.2 offset 1.5 shape smooth climax 0.9 duration 3",
        "expression anger: onset 0.5 offset 0.8 shape smooth climax 0.9 duration 2",
        "expression fear: onset 0.3 offset 0.9 shape exponential climax 1 duration 1.5",
        "expression disgust: onset 0.6 offset 0.8 shape smooth climax 0.8 duration 2",
        "expression surprise: onset 0.15 offset 1 shape exponential climax 1 duration 1.2",
        "blink: interval 4 jitter 1.2 duration 0.15 amplitude 1024",
        "nod: interval 8 jitter 2.5 duration 0.9 amplitude 4500",
        "head_motion: interval 3.5 jitter 1 duration 3 amplitude 2500",
        "gaze: interval 3 jitter 1 duration 0.2 amplitude 6000",
    ],
)


def lotta_visemes() -> dict[int, Recipe]:
    # lotta articulates broadly: a wider jaw, rounder and more protruded lips, more teeth
    return {
        1: Recipe({16: -100, 17: -90, 4: 20, 5: 20}, {"Lip presser": 1.0}),
        2: Recipe({3: 120, 5: 170, 10: 140, 11: 140, 16: -120, 4: -150, 8: -100, 9: -100}),
        3: Recipe({3: 270, 45: 200, 44: 360, 4: -90, 6: 90, 7: 90}),
        4: Recipe({3: 240, 44: 480, 45: 80, 6: 120, 7: 120, 4: -90}),
        5: Recipe({3: 320, 46: 340, 6: 90, 7: 90, 4: -50}),
        6: Recipe({3: 170, 16: 320, 17: 300, 6: -130, 7: -130, 53: -100, 54: -100, 4: -90,
                   5: -90}),
        7: Recipe({3: 60, 6: 230, 7: 230, 53: 170, 54: 170, 4: -150, 5: -170, 8: -90, 9: -90}),
        8: Recipe({3: 260, 44: 420, 6: 90, 7: 90, 4: -60}),
        9: Recipe({3: 200, 16: 200, 17: 190, 6: -110, 7: -110, 4: -60}),
        10: Recipe({3: 860, 6: 100, 7: 100, 4: -160, 8: -120, 9: -120, 5: -60}),
        11: Recipe({3: 440, 6: 260, 7: 260, 53: 170, 54: 170, 4: -140}),
        12: Recipe({3: 240, 6: 330, 7: 330, 53: 240, 54: 240, 12: 90, 13: 90, 4: -120}),
        13: Recipe({3: 640, 6: -120, 7: -120, 16: 170, 17: 170, 4: -80}),
        14: Recipe({3: 240, 6: -190, 7: -190, 53: -140, 54: -140, 16: 380, 17: 360}),
    }  # fmt: skip


def lotta_expressions() -> dict[str, Recipe]:
    # lotta's own faces: a lopsided grin (left side up, head tilted), brows in every feeling,
    # the head dropping when sad and pulled back in fear
    return {
        "joy": Recipe(
            {12: 420, 13: 250, 59: 380, 60: 220, 6: 260, 7: 150, 53: 230, 54: 130, 41: 480,
             42: 300, 21: 260, 22: 160, 4: -200, 3: 140, 5: -80, 31: 120, 32: 60, 33: 160,
             34: 90, 50: 5000, 48: -1500}
        ),
        "sadness": Recipe(
            {31: 380, 32: 380, 33: 60, 34: 60, 35: -150, 36: -150, 37: 80, 38: 80, 12: -260,
             13: -260, 59: -240, 60: -240, 19: 380, 20: 380, 18: 200, 5: 90, 16: 80, 48: 7000},
        ),
        "anger": Recipe(
            {37: 220, 38: 220, 31: -200, 32: -200, 33: -140, 34: -140, 19: 200, 20: 200,
             21: 300, 22: 300, 4: -80, 5: -60, 6: 100, 7: 100, 61: 120, 62: 120, 3: 90, 48: 2500},
            {"Brow lowerer": 1.0, "Upper lip raiser": 0.3, "Lid tightener": 0.4},
        ),
        "fear": Recipe(
            {31: 420, 32: 420, 33: 240, 34: 240, 35: 90, 36: 90, 37: 130, 38: 130, 19: -380,
             20: -380, 3: 280, 6: 260, 7: 260, 53: 220, 54: 220, 5: -150, 48: -3500},
        ),
        "disgust": Recipe(
            {4: -60, 51: -30, 12: -120, 13: 40, 59: -100, 60: 60, 31: -130, 32: -60, 21: 320,
             22: 200, 63: 160, 61: 140, 62: 90, 16: 140, 3: 60, 50: -3000},
            {"Nose wrinkler": 0.7, "Upper lip raiser": 0.4},
        ),
        "surprise": Recipe(
            {31: 480, 32: 480, 33: 520, 34: 520, 35: 440, 36: 440, 19: -420, 20: -420, 21: -80,
             22: -80, 3: 720, 6: -90, 7: -90, 4: -90, 48: -2500},
        ),
    }  # fmt: skip


LOTTA = Personality(
    name="lotta",
    title="lotta — the lively one",
    look=Look(
        seed=2008,
        skin=(206, 156, 122),
        blush=(200, 104, 92),
        lid=(170, 118, 100),
        lash=(28, 20, 18),
        brow=(40, 28, 24),
        lips=(176, 72, 74),
        hair=(44, 30, 26),
        iris=(104, 120, 62),
        teeth=(240, 236, 222),
    ),
    shape_units={
        "Head lower width": 0.35,
        "Chin width": 0.4,
        "Jaw z-extension": 0.25,
        "Nose lower vertical position": -0.35,
        "Nose middle vertical position": -0.25,
        "Nose lower z-extension": 0.45,
        "Nose middle z-extension": 0.3,
        "Eyebrows outer vertical position": 0.4,
        "Eyebrows inner vertical position": 0.3,
        "Eyebrows middle vertical position": 0.45,
        "Eyes separation distance": 0.3,
        "Eyes height": 0.45,
        "Eyes width": 0.1,
        "Mouth width": 0.35,
        "Mouth lip thickness": 1.1,
        "Cheeks z-extension": 0.35,
        "Mouth vertical position": -0.15,
    },  # fmt: skip
    eye_radius=0.155,
    pupil_angle=0.18,
    iris_angle=0.45,
    skull_centre=(0.0, 0.3, -0.74),
    skull_axes=(0.86, 1.2, 1.05),
    neck_radii=(0.36, 0.34),
    ear_size=(0.27, 0.16, 0.06),
    ear_centre=(0.86, 0.04, -0.8),
    hairline_front=0.9,
    hairline_temple=0.66,
    hairline_nape=-0.55,
    teeth_show=0.018,
    arch_depth=0.18,
    jaw_glide=0.3,
    visemes=lotta_visemes(),
    expressions=lotta_expressions(),
    temporal=[
        "expression joy: onset 0.25 offset 0.5 shape linear climax 1.2 duration 1.8",
        "expression sadness: onset 0.6 offset 0.7 shape linear climax 1 duration 2",
        "expression anger: onset 0.2 offset 0.5 shape linear climax 1.1 duration 1.5",
        "expression fear: onset 0.15 offset 0.6 shape linear climax 1.2 duration 1.2",
        "expression disgust: onset 0.3 offset 0.5 shape linear climax 1 duration 1.5",
        "expression surprise: onset 0.1 offset 0.6 shape linear climax 1.3 duration 1",
        "blink: interval 2.5 jitter 0.8 duration 0.1 amplitude 1024",
        "nod: interval 4.5 jitter 1.5 duration 0.6 amplitude 9000",
        "head_motion: interval 2 jitter 0.7 duration 1.6 amplitude 5000",
        "gaze: interval 1.8 jitter 0.6 duration 0.12 amplitude 10000",
    ],
)

PERSONALITIES = {p.name: p for p in (CYBATT, LOTTA)}

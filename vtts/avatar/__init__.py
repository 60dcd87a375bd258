"""Avatars of other engines: ARKit blendshapes and Oculus visemes.

- :mod:`vtts.avatar.arkit`: the 52 ARKit blendshape names (:data:`~vtts.avatar.arkit.ARKIT_NAMES`),
  the 15 Oculus visemes (:data:`~vtts.avatar.arkit.OCULUS_VISEMES`) and the recipe table
  (:func:`~vtts.avatar.arkit.recipes`): every FAP, viseme and expression as a weighted sum of ARKit
  shapes, read by the avatar import and, inverted, by the curves export;
- :mod:`vtts.avatar.curves`: curves out, the animation of ``vtts say``/``play`` as ARKit weights,
  Oculus viseme weights, Azure viseme events or TalkingHead's viseme track
  (:func:`~vtts.avatar.curves.write_curves`);
- :mod:`vtts.avatar.sapi`: the 22 SAPI visemes (Azure's ``viseme_id``) of MPEG-4 visemes and
  phones.
"""

from __future__ import annotations

from vtts.avatar.arkit import (
    ARKIT_NAMES,
    OCULUS_VISEMES,
    Recipe,
    RecipeTable,
    mpeg4_viseme,
    oculus_viseme,
    recipes,
)

__all__ = [
    "ARKIT_NAMES",
    "OCULUS_VISEMES",
    "Recipe",
    "RecipeTable",
    "mpeg4_viseme",
    "oculus_viseme",
    "recipes",
]

"""The environment the renderer sets up for Mesa before OpenGL is loaded."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

from vtts.render.pyrender_adapter import LLVMPIPE_MIN_THREADS, llvmpipe_threads


def test_llvmpipe_gets_at_least_the_minimum_of_threads():
    assert llvmpipe_threads() == max(LLVMPIPE_MIN_THREADS, os.cpu_count() or 1)


def _lp_after_loading(env: dict) -> str:
    code = (
        "import os; from vtts.render.pyrender_adapter import load_pyrender; load_pyrender(); "
        "print(os.environ['LP_NUM_THREADS'])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    return out.stdout.strip()


def test_llvmpipe_threads_are_set_unless_the_caller_chose():
    env = {k: v for k, v in os.environ.items() if k != "LP_NUM_THREADS"}
    assert _lp_after_loading(env) == str(llvmpipe_threads())
    assert _lp_after_loading({**env, "LP_NUM_THREADS": "1"}) == "1"  # e.g. one per batch worker


def test_an_appearance_without_material_is_unlit(tmp_path):
    """VRML97: an Appearance with no Material shows its texture's colours as they are."""
    from PIL import Image

    from vtts.face import load_model
    from vtts.render import FaceRenderer

    Image.fromarray(np.full((4, 4, 3), (200, 30, 90), np.uint8)).save(tmp_path / "t.png")
    quad = (
        "geometry IndexedFaceSet {{ coord Coordinate {{ point [-1 -1 0, 1 -1 0, 1 1 0, -1 1 0] }}"
        " coordIndex [0 1 2 3 -1] texCoord TextureCoordinate {{ point [0 0, 1 0, 1 1, 0 1] }} }}"
    )
    for material, lit in (("", False), ("material Material { diffuseColor 1 1 1 }", True)):
        (tmp_path / "m.wrl").write_text(
            "#VRML V2.0 utf8\nShape { appearance Appearance { "
            + material
            + ' texture ImageTexture { url "t.png" } } '
            + quad.format()
            + " }\n"
        )
        with FaceRenderer(load_model(str(tmp_path / "m.wrl")), size=(64, 64)) as r:
            centre = r.render(np.zeros(90))[32, 32]
        assert (tuple(centre) != (200, 30, 90)) == lit, (material, centre)


def test_a_texture_with_alpha_draws_as_a_cutout(tmp_path):
    """A texture whose alpha is 0 somewhere (a fitted head's glasses) is not drawn there: the
    quad behind shows through its left half, the front quad's colour shows on its right."""
    from PIL import Image

    from vtts.face import load_model
    from vtts.render import FaceRenderer

    rgba = np.zeros((4, 4, 4), np.uint8)
    rgba[..., :3] = (200, 30, 90)
    rgba[:, 2:, 3] = 255  # the right half shows
    Image.fromarray(rgba).save(tmp_path / "t.png")
    Image.fromarray(np.full((4, 4, 3), (20, 200, 40), np.uint8)).save(tmp_path / "b.png")

    def quad(z: float, url: str) -> str:
        return (
            f'Shape {{ appearance Appearance {{ texture ImageTexture {{ url "{url}" }} }} '
            f"geometry IndexedFaceSet {{ coord Coordinate {{ point [-1 -1 {z}, 1 -1 {z}, "
            f"1 1 {z}, -1 1 {z}] }} coordIndex [0 1 2 3 -1] "
            "texCoord TextureCoordinate { point [0 0, 1 0, 1 1, 0 1] } } }\n"
        )

    (tmp_path / "m.wrl").write_text("#VRML V2.0 utf8\n" + quad(0.0, "b.png") + quad(0.3, "t.png"))
    with FaceRenderer(load_model(str(tmp_path / "m.wrl")), size=(64, 64)) as r:
        img, numbers = r.render(np.zeros(90), triangles=True)
    assert tuple(img[32, 20]) == (20, 200, 40)  # the cut out half: the quad behind
    assert tuple(img[32, 44]) == (200, 30, 90)  # the drawn half, unlit
    assert numbers[32, 20] != numbers[32, 44]  # the triangle numbers see through it too


def test_a_black_specular_colour_draws_no_highlight(tmp_path):
    """A Material that sets ``specularColor 0 0 0`` (a photo-textured head's skin) draws a
    black surface black; one that leaves it at its default keeps the renderer's highlight."""
    from vtts.face import load_model
    from vtts.render import FaceRenderer

    quad = (
        "geometry IndexedFaceSet { coord Coordinate { point [-1 -1 0, 1 -1 0, 1 1 0, -1 1 0] }"
        " coordIndex [0 1 2 3 -1] }"
    )
    for specular, floor in (("", True), ("specularColor 0 0 0", False)):
        (tmp_path / "m.wrl").write_text(
            "#VRML V2.0 utf8\nShape { appearance Appearance { material Material { "
            f"diffuseColor 0 0 0 shininess 0.12 {specular} }} }} {quad} }}\n"
        )
        with FaceRenderer(load_model(str(tmp_path / "m.wrl")), size=(64, 64)) as r:
            centre = r.render(np.zeros(90))[32, 32]
        assert (int(centre.max()) > 8) == floor, (specular, centre)

"""Helpers of the glTF export tests: a small rig with every kind of Transform and table the export
encodes, parameter tracks that sweep the tables' intervals (and beyond), exported files read back
independently of the exporter (accessors, sparse ones too, the node tree, the animation at a
keyframe, morph targets applied), and the Khronos glTF-Validator run through node."""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pygltflib
import pytest

from vtts.face import N_PARAMS

ROOT = Path(__file__).parents[2]
DATA = ROOT / "tests" / "data"
HEAD = DATA / "models" / "head.wrl"
VALIDATOR = ROOT / "tools" / "node" / "validate_gltf.js"
DTYPES = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def validate(path: Path) -> dict:
    """The glTF-Validator's report on ``path``. Fails (never skips) when setup did not install
    node and the validator: ``scripts/setup.sh`` does."""
    node = shutil.which("node")
    installed = ROOT / "tools" / "node" / "node_modules" / "gltf-validator"
    if node is None or not installed.is_dir():
        pytest.fail(
            "the glTF-Validator is not installed (node and tools/node/node_modules): run "
            "scripts/setup.sh, which installs both"
        )
    done = subprocess.run(
        [node, str(VALIDATOR), str(path)], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def problems(report: dict) -> list[dict]:
    """The errors and warnings of a report (severity 0 and 1)."""
    return [m for m in report["issues"]["messages"] if m["severity"] <= 1]


class Decoded:
    """An exported file read back."""

    def __init__(self, path: Path) -> None:
        self.doc = pygltflib.GLTF2.load(str(path))
        buf = self.doc.buffers[0]
        if buf.uri is None:
            self.data = self.doc.binary_blob()
        else:
            head, _, payload = buf.uri.partition(",")
            assert head == "data:application/octet-stream;base64"
            self.data = base64.b64decode(payload)
        self.parents: dict[int, int] = {}
        for i, n in enumerate(self.doc.nodes):
            for c in n.children or []:
                assert c not in self.parents, "a node with two parents"
                self.parents[c] = i

    def view(self, index: int) -> bytes:
        v = self.doc.bufferViews[index]
        return self.data[v.byteOffset or 0 : (v.byteOffset or 0) + v.byteLength]

    def accessor(self, index: int) -> np.ndarray:
        a = self.doc.accessors[index]
        k = WIDTH[a.type]
        dtype = DTYPES[a.componentType]
        if a.bufferView is None:
            out = np.zeros((a.count, k), dtype=dtype)
        else:
            raw = self.view(a.bufferView)[a.byteOffset or 0 :]
            out = np.frombuffer(raw, dtype=dtype, count=a.count * k).reshape(a.count, k).copy()
        if a.sparse is not None:
            s = a.sparse
            idx = np.frombuffer(
                self.view(s.indices.bufferView), dtype=DTYPES[s.indices.componentType],
                count=s.count,
            )  # fmt: skip
            vals = np.frombuffer(self.view(s.values.bufferView), dtype=dtype, count=s.count * k)
            assert np.all(np.diff(idx.astype(np.int64)) > 0), "sparse indices must increase"
            out[idx] = vals.reshape(s.count, k)
        return out

    def node_named(self, name: str) -> int:
        found = [i for i, n in enumerate(self.doc.nodes) if n.name == name]
        assert len(found) == 1, f"{len(found)} nodes named {name}"
        return found[0]

    # ---- the animation at a keyframe ----------------------------------------------------------

    def channels(self, frame: int) -> dict[tuple[int, str], np.ndarray]:
        """(node, path) → the animated value at keyframe ``frame``."""
        out = {}
        for anim in self.doc.animations:
            for ch in anim.channels:
                s = anim.samplers[ch.sampler]
                assert s.interpolation == "LINEAR"
                values = self.accessor(s.output).astype(np.float64)
                n = self.accessor(s.input).shape[0]
                per = values.reshape(n, -1)
                out[(ch.target.node, ch.target.path)] = per[frame]
        return out

    def local(self, node: int, anim: dict) -> np.ndarray:
        n = self.doc.nodes[node]
        if n.matrix is not None:
            return np.array(n.matrix, dtype=np.float64).reshape(4, 4).T
        t = anim.get((node, "translation"), n.translation or [0, 0, 0])
        q = anim.get((node, "rotation"), n.rotation or [0, 0, 0, 1])
        s = anim.get((node, "scale"), n.scale or [1, 1, 1])
        x, y, z, w = (float(v) for v in q)
        r = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        m = np.eye(4)
        m[:3, :3] = r @ np.diag(np.asarray(s, dtype=np.float64))
        m[:3, 3] = t
        return m

    def world(self, node: int, anim: dict) -> np.ndarray:
        m = self.local(node, anim)
        while node in self.parents:
            node = self.parents[node]
            m = self.local(node, anim) @ m
        return m

    def mesh_positions(self, node: int, anim: dict) -> tuple[np.ndarray, np.ndarray]:
        """(local positions ``(V, 3)`` with the node's morph weights applied, normals
        ``(V, 3)`` likewise, renormalized)."""
        n = self.doc.nodes[node]
        (prim,) = self.doc.meshes[n.mesh].primitives
        pos = self.accessor(prim.attributes.POSITION).astype(np.float64)
        nor = self.accessor(prim.attributes.NORMAL).astype(np.float64)
        weights = anim.get((node, "weights"))
        if prim.targets:
            assert weights is not None and len(weights) == len(prim.targets)
            for w, t in zip(weights, prim.targets, strict=True):
                pos += w * self.accessor(t["POSITION"] if isinstance(t, dict) else t.POSITION)
                tn = t.get("NORMAL") if isinstance(t, dict) else t.NORMAL
                if tn is not None:
                    nor += w * self.accessor(tn)
        nor /= np.linalg.norm(nor, axis=1, keepdims=True)
        return pos, nor

    def faces(self, node: int) -> np.ndarray:
        (prim,) = self.doc.meshes[self.doc.nodes[node].mesh].primitives
        return self.accessor(prim.indices).reshape(-1, 3).astype(np.int64)

    def triangles(self, frame: int) -> dict[str, list[np.ndarray]]:
        """Mesh node name → per instance the world corners ``(m, 3, 3)`` of its triangles at
        keyframe ``frame``."""
        anim = self.channels(frame)
        out: dict[str, list[np.ndarray]] = {}
        for i, n in enumerate(self.doc.nodes):
            if n.mesh is None:
                continue
            pos, _ = self.mesh_positions(i, anim)
            m = self.world(i, anim)
            world = pos @ m[:3, :3].T + m[:3, 3]
            out.setdefault(n.name, []).append(world[self.faces(i)])
        return out

    def times(self) -> np.ndarray:
        (anim,) = self.doc.animations
        return self.accessor(anim.samplers[0].input).reshape(-1)


# ---- the rig and parameter sweeps ----------------------------------------------------------------

# A 3x3 grid of points (and one no face uses) under a jaw Transform with a center, in a root
# Transform with a rotation, a non-uniform scale and a scaleOrientation; a texture seam at point 4
# and flat normals (creaseAngle 0), so the mesh has seam copies; the grid's jaw is USEd a second
# time; an eye (a Sphere) turned about two axes and pushed, and a Box squashed along a turned axis.
RIG_WRL = """#VRML V2.0 utf8
DEF RIG Transform {
  translation 0.1 0.2 0.3
  rotation 0 1 0 0.3
  scale 1 1.2 0.9
  scaleOrientation 0 0 1 0.4
  center 0.05 0 0
  children [
    DEF JAW Transform {
      center 0 -0.2 0
      children [
        Shape {
          appearance Appearance {
            material Material { diffuseColor 0.9 0.7 0.6 shininess 0.3 }
            texture PixelTexture { image 2 2 3 0xff0000 0x00ff00 0x0000ff 0xffffff }
          }
          geometry DEF LIP IndexedFaceSet {
            coord Coordinate { point [ -0.2 -0.2 0, 0 -0.2 0, 0.2 -0.2 0,
                                       -0.2 0 0, 0 0 0.02, 0.2 0 0,
                                       -0.2 0.2 0, 0 0.2 0, 0.2 0.2 0, 0 0 0.01 ] }
            coordIndex [ 0 1 4 3 -1 1 2 5 4 -1 3 4 7 6 -1 4 5 8 7 -1 ]
            texCoord TextureCoordinate { point [ 0 0, 0.5 0, 1 0, 0 0.5, 0.5 0.5, 1 0.5,
                                                 0 1, 0.5 1, 1 1, 0.9 0.9 ] }
            texCoordIndex [ 0 1 4 3 -1 1 2 5 4 -1 3 4 7 6 -1 9 5 8 7 -1 ]
          }
        }
      ]
    }
    Transform { translation 0 -0.6 0 children [ USE JAW ] }
    DEF EYE Transform {
      center 0.2 0.3 0
      children [
        Shape {
          appearance Appearance { material Material { diffuseColor 1 1 1 } }
          geometry Sphere { radius 0.05 }
        }
      ]
    }
    DEF SQUASH Transform {
      translation -0.3 0.3 0
      scaleOrientation 0 0 1 0.5
      children [ Shape { geometry Box { size 0.1 0.1 0.1 } } ]
    }
  ]
}
"""

RIG_ADT = """#AnimationDefinitionTables

MIAP 3 (open_jaw)
IndexedFaceSet: LIP
interval borders: -100 0 200 400
displacements:
vertex 0 0 0.0001 0 0 -0.0002 0 0 -0.0001 0.00005
vertex 1 0 0.0001 0 0 -0.0003 0 0.0001 -0.0001 0
vertex 4 0 0 0.0002 0 -0.0001 0 0 -0.0002 0
Transform: JAW
rotation neutral value: 1 0 0 (axis) 0 (angle)
per unit: 0.001

MIAP 23 (yaw_l_eyeball)
Transform: EYE
rotation neutral value: 0 1 0 (axis) 0 (angle)
per unit: 0.0005

MIAP 25 (pitch_l_eyeball)
Transform: EYE
rotation neutral value: 1 0 0 (axis) 0 (angle)
per unit: 0.0004

MIAP 27 (thrust_l_eyeball)
Transform: EYE
translation neutral value: 0 0 0
per unit: 0 0 0.001

MIAP viseme 1 (p, b, m)
IndexedFaceSet: LIP
interval borders: 0 1
displacements:
vertex 7 0 -0.05 0
vertex 8 0.01 -0.04 0.01

MIAP expression 1 (joy)
IndexedFaceSet: LIP
interval borders: 0 0.5 1
displacements:
vertex 6 0.02 0.02 0 0.01 0.01 0
vertex 2 0.01 0 0 0.01 0 0.03
Transform: SQUASH
scale neutral value: 1 1 1
per unit: 0.5 0.2 0
"""


def write_rig(folder: Path) -> Path:
    """The rig's ``.wrl`` and ``.adt`` in ``folder``; returns the ``.wrl``."""
    wrl = folder / "rig.wrl"
    wrl.write_text(RIG_WRL, encoding="utf-8")
    wrl.with_suffix(".adt").write_text(RIG_ADT, encoding="utf-8")
    return wrl


def sweep(model, n_frames: int = 12, seed: int = 0) -> np.ndarray:
    """``(n_frames, N_PARAMS)``: every MIAP of ``model`` from below its lowest interval border to
    beyond its highest (extrapolated ends included), each at its own pace, plus noise."""
    rng = np.random.default_rng(seed)
    out = np.zeros((n_frames, N_PARAMS))
    s = np.linspace(0.0, 1.0, n_frames)
    for miap, adt in model.tables.adts.items():
        borders = [m.borders for m in adt.meshes]
        lo = min((b[0] for b in borders), default=-1000.0 if miap.kind == "fap" else -1.0)
        hi = max((b[-1] for b in borders), default=1000.0 if miap.kind == "fap" else 1.0)
        span = hi - lo
        phase = rng.uniform(0, 1)
        out[:, miap.index] = lo - 0.2 * span + 1.4 * span * ((s + phase) % 1.0)
        out[:, miap.index] += rng.normal(0, 0.01 * span, n_frames)
    out[0] = 0.0  # the neutral face first
    return out

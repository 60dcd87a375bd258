"""Taking the talking head out of vtts: animated glTF 2.0 (:func:`write_gltf`,
:func:`animation_gltf`), for Blender, three.js and other glTF viewers.

See ``docs/web.md`` ("glTF encoding") for what the file holds.
"""

from vtts.export.gltf import CAMERA_NODE, animation_gltf, placement, write_gltf
from vtts.gltf import GLTF_SUFFIXES

__all__ = ["CAMERA_NODE", "GLTF_SUFFIXES", "animation_gltf", "placement", "write_gltf"]

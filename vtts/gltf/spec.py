"""Numbers and names of the glTF 2.0 specification that the reader and the writer share."""

from __future__ import annotations

import numpy as np

#: bufferView targets: vertex attributes, and triangle indices.
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963

#: componentType codes.
BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT, UNSIGNED_INT, FLOAT = 5120, 5121, 5122, 5123, 5125, 5126
#: numpy dtype of each componentType.
COMPONENT_TYPES: dict[int, np.dtype] = {
    BYTE: np.dtype("<i1"),
    UNSIGNED_BYTE: np.dtype("<u1"),
    SHORT: np.dtype("<i2"),
    UNSIGNED_SHORT: np.dtype("<u2"),
    UNSIGNED_INT: np.dtype("<u4"),
    FLOAT: np.dtype("<f4"),
}
#: What a normalized integer component is divided by (signed ones are then clamped at −1).
NORMALIZE = {
    BYTE: 127.0,
    UNSIGNED_BYTE: 255.0,
    SHORT: 32767.0,
    UNSIGNED_SHORT: 65535.0,
    UNSIGNED_INT: 4294967295.0,
}
#: The componentTypes of sparse indices and triangle indices.
INDEX_TYPES = (UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT)
#: Components of each accessor type.
COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
#: The largest byteStride glTF allows.
MAX_STRIDE = 252

#: Primitive modes: the three drawn as triangles, and the names of the others.
TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN = 4, 5, 6
MODE_NAMES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP"}

#: Sampler wrap modes and filters.
REPEAT, CLAMP_TO_EDGE = 10497, 33071
LINEAR, LINEAR_MIPMAP_LINEAR = 9729, 9987

DRACO = "KHR_draco_mesh_compression"
MESHOPT = ("EXT_meshopt_compression", "KHR_meshopt_compression")
BASISU = "KHR_texture_basisu"
QUANTIZATION = "KHR_mesh_quantization"
UNLIT = "KHR_materials_unlit"
TEXTURE_TRANSFORM = "KHR_texture_transform"
WEBP = "EXT_texture_webp"
#: Extensions a file may require: read (or, for textures, dropped with a warning).
SUPPORTED_REQUIRED = frozenset(
    {QUANTIZATION, DRACO, *MESHOPT, BASISU, UNLIT, TEXTURE_TRANSFORM, WEBP}
)

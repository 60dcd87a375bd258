"""glTF 2.0 in and out, with nothing of faces in it: the one reader (:class:`GltfReader`, for
``adi import`` and ``adi build``), the buffer builder (:class:`BufferBuilder`) and the writer
(:func:`write_document`, :func:`glb_chunks`) that the exports use, and the compression extensions
(Draco, meshopt) and images they meet.

Modules, after trimesh's ``exchange/gltf``:

- :mod:`~vtts.gltf.spec`      the specification's numbers and names (component types, targets,
  extensions);
- :mod:`~vtts.gltf.reader`    :class:`GltfReader`: a file's buffers, accessors, meshes,
  materials, images and nodes, every index and size checked;
- :mod:`~vtts.gltf.buffers`   :class:`BufferBuilder`: arrays packed into one buffer;
- :mod:`~vtts.gltf.writer`    ``.glb`` / ``.gltf`` written atomically;
- :mod:`~vtts.gltf.draco`, :mod:`~vtts.gltf.meshopt`  the compression extensions, decoded;
- :mod:`~vtts.gltf.images`    texture images (PNG and JPEG kept, others as PNG);
- :mod:`~vtts.gltf.uri`       data uris and files beside the ``.gltf``;
- :mod:`~vtts.gltf.geometry`  quaternions, strips and fans, texture transforms.

The face-specific parts (morph targets from ADTs, head scenes, the web player) are in
:mod:`vtts.export`.
"""

from vtts.gltf.buffers import BufferBuilder
from vtts.gltf.images import image_file
from vtts.gltf.reader import GltfReader, Image, Material, Mesh, Primitive
from vtts.gltf.spec import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER
from vtts.gltf.writer import GLTF_SUFFIXES, glb_chunks, write_document

__all__ = [
    "ARRAY_BUFFER",
    "ELEMENT_ARRAY_BUFFER",
    "GLTF_SUFFIXES",
    "BufferBuilder",
    "GltfReader",
    "Image",
    "Material",
    "Mesh",
    "Primitive",
    "glb_chunks",
    "image_file",
    "write_document",
]

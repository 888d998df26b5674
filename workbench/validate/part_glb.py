"""The decorated part as a binary glTF whose print and coverage are two layers over one surface."""

from __future__ import annotations

import json
import struct

import cv2
import numpy as np

from workbench.mesh.normals import vertex_normals

# glTF's component types and buffer targets (glTF 2.0, 3.6.2.2 and 3.6.1)
_FLOAT, _UINT32 = 5126, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_LINEAR, _LINEAR_MIPMAP_LINEAR, _CLAMP = 9729, 9987, 33071


def layered_glb(V: np.ndarray, F: np.ndarray, uv: np.ndarray, layers: list[tuple[str, bytes, str, bool]]) -> bytes:
    """Binary glTF of a textured mesh, one node per texture layer, all sharing one geometry.

    The first layer is shown; a viewer shows another by switching the nodes' visibility
    (the geometry is stored once: a layer costs its picture alone). Written by hand rather
    than through trimesh, which stores one texture per mesh and re-encodes it as PNG: here a
    print's picture stays a JPEG (a tenth of the bytes) and a coverage map a PNG (exact colours).

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles, counter-clockwise seen from the decorated side.
    uv : (#V, 2) float
        Texture coordinates, glTF's: u right, v down, (0, 0) at the picture's top-left corner.
    layers : list of (name, picture bytes, MIME type, lit)
        Each layer's name (its node's and material's), encoded picture (``image/jpeg`` or
        ``image/png``) spanning the same texture coordinates, and whether it is shaded by light
        (False: its colours shown as they are, KHR_materials_unlit: a map whose legend must match).

    Returns
    -------
    bytes
        The GLB: deterministic for the same arrays and pictures.
    """
    V = np.ascontiguousarray(V, np.float32)
    F = np.ascontiguousarray(F, np.uint32)
    N = np.ascontiguousarray(vertex_normals(np.asarray(V, np.float64), np.asarray(F, np.int64)), np.float32)
    uv = np.ascontiguousarray(uv, np.float32)
    chunks: list[bytes] = []
    views: list[dict] = []

    def add(data: bytes, target: int | None = None) -> int:
        offset = sum(len(c) for c in chunks)
        chunks.append(data + b"\0" * (-len(data) % 4))  # every view 4-byte aligned
        views.append(
            {"buffer": 0, "byteOffset": offset, "byteLength": len(data)} | ({"target": target} if target else {})
        )
        return len(views) - 1

    accessors = [
        {
            "bufferView": add(V.tobytes(), _ARRAY_BUFFER),
            "componentType": _FLOAT,
            "count": len(V),
            "type": "VEC3",
            "min": V.min(axis=0).tolist(),
            "max": V.max(axis=0).tolist(),
        },
        {"bufferView": add(N.tobytes(), _ARRAY_BUFFER), "componentType": _FLOAT, "count": len(N), "type": "VEC3"},
        {"bufferView": add(uv.tobytes(), _ARRAY_BUFFER), "componentType": _FLOAT, "count": len(uv), "type": "VEC2"},
        {
            "bufferView": add(F.tobytes(), _ELEMENT_ARRAY_BUFFER),
            "componentType": _UINT32,
            "count": F.size,
            "type": "SCALAR",
        },
    ]
    primitive = {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3}
    images, materials, meshes, nodes = [], [], [], []
    for k, (name, picture, mime, lit) in enumerate(layers):
        images.append({"bufferView": add(picture), "mimeType": mime, "name": name})
        material = {
            "name": name,
            "pbrMetallicRoughness": {"baseColorTexture": {"index": k}, "metallicFactor": 0.0, "roughnessFactor": 0.7},
            # (an open shell: its back shows through its holes and past its rim)
            "doubleSided": True,
        }
        if not lit:
            material["extensions"] = {"KHR_materials_unlit": {}}
        materials.append(material)
        meshes.append({"name": name, "primitives": [{**primitive, "material": k}]})
        nodes.append({"name": name, "mesh": k})
    binary = b"".join(chunks)
    gltf = {
        "asset": {"version": "2.0", "generator": "workbench"},
        **({"extensionsUsed": ["KHR_materials_unlit"]} if not all(lit for *_, lit in layers) else {}),
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "textures": [{"sampler": 0, "source": k} for k in range(len(layers))],
        "samplers": [{"magFilter": _LINEAR, "minFilter": _LINEAR_MIPMAP_LINEAR, "wrapS": _CLAMP, "wrapT": _CLAMP}],
        "images": images,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(binary)}],
    }
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)  # the JSON chunk padded with spaces (glTF 2.0, 4.4.3.1)
    body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(binary), b"BIN\0") + binary
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def print_uv(flat_mm: np.ndarray, rect_height_mm: float, image_size_mm: tuple[float, float]) -> np.ndarray:
    """glTF texture coordinates of the print's picture at flat positions.

    Parameters
    ----------
    flat_mm : (#V, 2) float
        Flat positions, mm, y up, the design rectangle's bottom-left at the origin (flat.obj's).
    rect_height_mm : float
        Height of the design rectangle, whose top edge is the picture's top edge.
    image_size_mm : (float, float)
        Width and height the print's picture covers, mm.

    Returns
    -------
    (#V, 2) float
        u right, v down from the picture's top-left corner: print mm (y down) over the picture's size.
    """
    x = flat_mm[:, 0] / image_size_mm[0]
    y = (rect_height_mm - flat_mm[:, 1]) / image_size_mm[1]
    return np.stack([x, y], axis=1)


def grid_on_texture(image: np.ndarray, px_per_mm: float, size_px: tuple[int, int], size_mm: tuple[float, float]):
    """A picture of the print's analysis grid resampled (nearest) onto a texture of the print's extent.

    Parameters
    ----------
    image : (rows, cols, 3) uint8
        The grid's picture: pixel (i, j) centred at ((j + 0.5) / px_per_mm, (i + 0.5) / px_per_mm) print mm.
    px_per_mm : float
        The grid's resolution.
    size_px : (int, int)
        The texture's width and height, pixels.
    size_mm : (float, float)
        The width and height it covers, print mm (the print's picture's).

    Returns
    -------
    (height, width, 3) uint8
        Each texture pixel takes the grid pixel under its centre; beyond the grid, the grid's last
        row or column (off the part there: no triangle samples it).
    """
    w, h = size_px
    x = ((np.arange(w) + 0.5) * size_mm[0] / w * px_per_mm - 0.5).astype(np.float32)
    y = ((np.arange(h) + 0.5) * size_mm[1] / h * px_per_mm - 0.5).astype(np.float32)
    mx, my = np.meshgrid(x, y)
    return cv2.remap(image, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)

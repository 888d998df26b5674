"""Writing results: PNG with its resolution, textured OBJ/MTL and GLB."""

from __future__ import annotations

import io
import struct
import zlib

import cv2
import numpy as np


def png_bytes(rgb: np.ndarray, dpi: float | None = None, compression: int = 3, fast: bool = False) -> bytes:
    """PNG of an RGB image, with its resolution stored in a pHYs chunk.

    OpenCV's encoder (fast, reproducible) writes no resolution, so the pHYs chunk is
    inserted after IHDR: pixels per metre, rounded as the format requires
    (600 dpi is stored as 23622 px/m and reads back as 599.9988 dpi).

    Parameters
    ----------
    rgb : (H, W, 3), (H, W, 4) or (H, W) uint8
        Image, RGB (or RGBA) order.
    dpi : float, optional
        Resolution to record.
    compression : int
        zlib level 0-9.
    fast : bool
        Every row filtered by its difference to the row above (libpng otherwise tries its five
        filters on every row and keeps the best): 40 % less time for files 1 to 7 % larger (a
        photo and a print's picture), the same pixels. Where OpenCV cannot choose the filter
        (before 4.11), the usual encoding.

    Returns
    -------
    bytes
    """
    if rgb.ndim == 2:
        img = rgb
    else:
        img = cv2.cvtColor(rgb, cv2.COLOR_RGBA2BGRA if rgb.shape[2] == 4 else cv2.COLOR_RGB2BGR)
    params = [cv2.IMWRITE_PNG_COMPRESSION, compression]
    if fast and hasattr(cv2, "IMWRITE_PNG_FILTER"):
        params += [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_UP]
    ok, buf = cv2.imencode(".png", img, params)
    if not ok:
        raise RuntimeError("PNG encoding failed")
    data = buf.tobytes()
    if dpi is None:
        return data
    ppm = int(round(dpi / 0.0254))
    body = b"pHYs" + struct.pack(">IIB", ppm, ppm, 1)
    chunk = struct.pack(">I", 9) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)
    ihdr_end = 8 + 8 + 13 + 4  # signature, IHDR length+type, IHDR data, CRC
    return data[:ihdr_end] + chunk + data[ihdr_end:]


def png_dpi(data: bytes) -> float | None:
    """Resolution recorded in a PNG's pHYs chunk, dpi (None when absent)."""
    pos = 8
    while pos + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[pos : pos + 8])
        if kind == b"pHYs":
            x, _, unit = struct.unpack(">IIB", data[pos + 8 : pos + 17])
            return x * 0.0254 if unit == 1 else None
        if kind == b"IDAT":
            return None
        pos += 12 + length
    return None


def texture_uv(uv_mm: np.ndarray, image_width_mm: float, image_height_mm: float, rect_height_mm: float) -> np.ndarray:
    """OBJ texture coordinates of flat positions: u right, v up, (0, 0) at the image's bottom-left.

    Parameters
    ----------
    uv_mm : (#V, 2) float
        Flat positions, mm, y up, the design rectangle's bottom-left at the origin.
    image_width_mm, image_height_mm : float
        Size the print image covers (whole pixels: slightly more than the rectangle).
    rect_height_mm : float
        Height of the design rectangle, whose top edge is the image's top edge.

    Returns
    -------
    (#V, 2) float
    """
    u = uv_mm[:, 0] / image_width_mm
    # distance below the image's top edge is rect_height - y
    v = 1.0 - (rect_height_mm - uv_mm[:, 1]) / image_height_mm
    return np.stack([u, v], axis=1)


def decorated_obj(
    V: np.ndarray,
    F: np.ndarray,
    vt: np.ndarray,
    name: str,
    texture: str,
    groups: list[tuple[str, str, int, int]] | None = None,
) -> tuple[bytes, bytes]:
    """OBJ and MTL of the decorated part: vertices in input order, one vt per vertex.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles.
    vt : (#V, 2) float
        Texture coordinates (:func:`texture_uv`).
    name : str
        Base name of the MTL file.
    texture : str
        Texture file name as the MTL refers to it.
    groups : list of (material, texture, first face, end face), optional
        Several films: faces [first, end) use their own material and texture (``vt``
        then points into that texture); default one material ``print`` for all.

    Returns
    -------
    obj, mtl : bytes
    """
    groups = groups or [("print", texture, 0, len(F))]
    lines = ["# workbench decorated part", f"mtllib {name}.mtl"]
    lines += [f"v {x:.12g} {y:.12g} {z:.12g}" for x, y, z in V.tolist()]
    lines += [f"vt {u:.10f} {v:.10f}" for u, v in vt.tolist()]
    mtl = ["# workbench decorated part"]
    for material, image, lo, hi in groups:
        lines.append(f"usemtl {material}")
        # f v/vt with the same index: the texture coordinates follow the vertex numbering
        lines += list(map("f {0}/{0} {1}/{1} {2}/{2}".format, *(F[lo:hi] + 1).T.tolist()))
        mtl.append(f"newmtl {material}\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd {image}")
    return ("\n".join(lines) + "\n").encode(), ("\n".join(mtl) + "\n").encode()


def decorated_glb(
    V: np.ndarray,
    F: np.ndarray,
    vt: np.ndarray,
    rgb: np.ndarray,
    max_texture_px: int = 4096,
    parts: list[tuple[str, int, int, np.ndarray]] | None = None,
) -> bytes:
    """Binary glTF of the decorated part with its texture embedded.

    glTF viewers and GPUs take textures up to 4096 to 16384 pixels, so the texture is
    reduced (area averaging) to ``max_texture_px`` on its longer side; the OBJ keeps
    the full-resolution print. trimesh converts v to glTF's top-left origin.

    Parameters
    ----------
    parts : list of (name, first face, end face, rgb), optional
        Several films: faces [first, end) form a mesh of their own with that film's
        print as texture (``vt`` points into it); default one mesh with ``rgb``.

    Returns
    -------
    bytes
    """
    import trimesh
    from PIL import Image

    def textured(Fp: np.ndarray, image: np.ndarray) -> trimesh.Trimesh:
        h, w = image.shape[:2]
        s = min(1.0, max_texture_px / max(h, w))
        if s < 1.0:
            image = cv2.resize(image, (max(int(w * s), 1), max(int(h * s), 1)), interpolation=cv2.INTER_AREA)
        used, local = np.unique(Fp, return_inverse=True)
        mesh = trimesh.Trimesh(V[used], local.reshape(-1, 3), process=False)
        mesh.visual = trimesh.visual.TextureVisuals(uv=vt[used], image=Image.fromarray(image))
        return mesh

    if parts is None:
        obj = textured(F, rgb)
    else:
        obj = trimesh.Scene()
        for name, lo, hi, image in parts:
            obj.add_geometry(textured(F[lo:hi], image), geom_name=name, node_name=name)
    buf = io.BytesIO()
    obj.export(buf, file_type="glb")
    return buf.getvalue()

"""ICC profiles: sRGB, and the default CMYK output profile built from a public characterisation.

The default output profile (``workbench/printing/data/workbench-coated-pt1.icc``) is built by
:func:`build_cmyk_profile` and regenerated with ``python -m workbench.printing.icc``. Its
source is public: the CIELAB (D50, 2°) aims of ISO 12647-2:2004 for paper type 1 (gloss
coated) — paper, the four solids and the three two-colour and the three-colour
overprints — through a Yule-Nielsen modified spectral Neugebauer model (n = 2, applied
to XYZ instead of spectra) with a 12 % tone value increase at 50 %. It is a model of a
standard press, not a measurement of one: a shop passes its own profile
(``workbench pdf --output-profile``), which is what its press and RIP were characterised with.

Encodings (ICC.1:2001-04, version 2): CMYK 0 to 1 as 0 to 65535 (0: no ink); the PCS is
CIELAB with L* 0 to 100 as 0 to 0xFF00 and a*, b* -128 to 127.996 as 0 to 0xFFFF
(``(a + 128) * 256``), relative to the paper (media white at L* = 100, a* = b* = 0).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

DATA = Path(__file__).parent / "data"
DEFAULT_CMYK_PROFILE = DATA / "workbench-coated-pt1.icc"
D50 = np.array([0.9642, 1.0, 0.8249])

# ISO 12647-2:2004, paper type 1 (gloss coated, white backing), CIELAB D50/2°
PT1_LAB = {
    "paper": (95.0, 0.0, -2.0),
    "C": (55.0, -37.0, -50.0),
    "M": (48.0, 74.0, -3.0),
    "Y": (89.0, -5.0, 93.0),
    "K": (16.0, 0.0, 0.0),
    "MY": (47.0, 68.0, 48.0),
    "CY": (50.0, -65.0, 27.0),
    "CM": (24.0, 22.0, -46.0),
    "CMY": (23.0, 0.0, 0.0),
}
TVI_50 = 0.12  # tone value increase at 50 % (ISO 12647-2 PT1, positive plates: 12 to 14 %)
YULE_NIELSEN_N = 2.0
SURFACE_REFLECTION = 0.008  # share of light the ink's surface reflects unchanged: the press's black point
TOTAL_INK_LIMIT = 3.2  # the profile's own separation never exceeds 320 %
COPYRIGHT = "Free to use and redistribute. Built by workbench from the ISO 12647-2:2004 PT1 CIELAB aims."


def lab_to_xyz(lab: np.ndarray, white: np.ndarray = D50) -> np.ndarray:
    """CIELAB to CIE XYZ (Y of the white = 1); (..., 3) float."""
    lab = np.asarray(lab, dtype=np.float64)
    fy = (lab[..., 0] + 16) / 116
    f = np.stack([fy + lab[..., 1] / 500, fy, fy - lab[..., 2] / 200], axis=-1)
    e = 6 / 29
    return white * np.where(f > e, f**3, 3 * e * e * (f - 4 / 29))


def xyz_to_lab(xyz: np.ndarray, white: np.ndarray = D50) -> np.ndarray:
    """CIE XYZ to CIELAB; (..., 3) float."""
    t = np.asarray(xyz, dtype=np.float64) / white
    e = 6 / 29
    f = np.where(t > e**3, np.cbrt(np.maximum(t, 0)), t / (3 * e * e) + 4 / 29)
    return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]), 200 * (f[..., 1] - f[..., 2])], axis=-1)


def _primaries() -> np.ndarray:
    """The 16 Neugebauer primaries' XYZ, indexed by the bits c + 2 m + 4 y + 8 k; (16, 3)."""
    xyz = {k: lab_to_xyz(v) for k, v in PT1_LAB.items()}
    names = ["paper", "C", "M", "CM", "Y", "CY", "MY", "CMY"]
    P = np.empty((16, 3))
    for bits in range(8):
        P[bits] = xyz[names[bits]]
        # black over a colour: the colour filtered by the black ink's own transmittance
        # (black's solid relative to paper); the surface reflection keeps a floor
        P[bits + 8] = xyz[names[bits]] * (xyz["K"] / xyz["paper"])
    return P


def cmyk_to_xyz(cmyk: np.ndarray) -> np.ndarray:
    """The press model: CMYK ink coverage (..., 4) in [0, 1] to absolute CIE XYZ (..., 3), D50."""
    a = np.clip(np.asarray(cmyk, dtype=np.float64), 0, 1)
    a = a + 4 * TVI_50 * a * (1 - a)  # mechanical dot gain: +TVI_50 at 50 %
    P = _primaries() ** (1 / YULE_NIELSEN_N)
    out = np.zeros((*a.shape[:-1], 3))
    for bits in range(16):
        w = np.ones(a.shape[:-1])
        for ch in range(4):
            w = w * (a[..., ch] if bits >> ch & 1 else 1 - a[..., ch])  # Demichel
        out += w[..., None] * P[bits]
    paper = lab_to_xyz(PT1_LAB["paper"])
    return (1 - SURFACE_REFLECTION) * out**YULE_NIELSEN_N + SURFACE_REFLECTION * paper


def cmyk_to_lab_relative(cmyk: np.ndarray) -> np.ndarray:
    """CMYK to CIELAB relative to the paper (the paper at L* = 100: the PCS of the profile's A2B0)."""
    paper = lab_to_xyz(PT1_LAB["paper"])
    return xyz_to_lab(cmyk_to_xyz(cmyk) / paper * D50)


def _grey_component(L: np.ndarray) -> np.ndarray:
    """Black generation: K by lightness (relative L*), none above L* 70, rising to 90 % at L* 10."""
    return 0.9 * np.clip((70.0 - L) / 60.0, 0, 1) ** 1.5


def separate(lab_rel: np.ndarray, iterations: int = 40) -> np.ndarray:
    """Inverse of the press model: relative CIELAB (n, 3) to CMYK (n, 4) in [0, 1].

    K follows the lightness (:func:`_grey_component`, reduced where the colour is
    chromatic), then C, M, Y by a projected Gauss-Newton solve in CIELAB with the total
    ink kept under :data:`TOTAL_INK_LIMIT`. Colours out of the gamut land on its surface
    near the closest printable colour.
    """
    lab_rel = np.asarray(lab_rel, dtype=np.float64)
    n = len(lab_rel)
    chroma = np.hypot(lab_rel[:, 1], lab_rel[:, 2])
    k = _grey_component(lab_rel[:, 0]) * np.clip(1 - chroma / 60.0, 0.25, 1)
    cmy = np.full((n, 3), 0.3)
    h = 1e-4
    for _ in range(iterations):
        x = np.column_stack([cmy, k])
        f0 = cmyk_to_lab_relative(x)
        J = np.empty((n, 3, 3))
        for ch in range(3):
            xp = x.copy()
            xp[:, ch] += h
            J[:, :, ch] = (cmyk_to_lab_relative(xp) - f0) / h
        r = lab_rel - f0
        # damped normal equations: well posed at the gamut's edges too
        JtJ = np.einsum("nij,nik->njk", J, J) + 1e-3 * np.eye(3)
        step = np.linalg.solve(JtJ, np.einsum("nij,ni->nj", J, r)[..., None])[..., 0]
        cmy = np.clip(cmy + np.clip(step, -0.25, 0.25), 0, 1)
        over = cmy.sum(axis=1) + k - TOTAL_INK_LIMIT
        total = np.maximum(cmy.sum(axis=1), 1e-12)
        cmy = np.where(over[:, None] > 0, cmy * ((total - over) / total)[:, None], cmy)
    return np.column_stack([cmy, k])


def _s15(v: float) -> bytes:
    return struct.pack(">i", int(round(v * 65536)))


def _tag_desc(text: str) -> bytes:
    a = text.encode("ascii") + b"\0"
    return b"desc" + b"\0" * 4 + struct.pack(">I", len(a)) + a + struct.pack(">II", 0, 0) + b"\0\0\0" + b"\0" * 67


def _tag_text(text: str) -> bytes:
    return b"text" + b"\0" * 4 + text.encode("ascii") + b"\0"


def _tag_xyz(xyz) -> bytes:
    return b"XYZ " + b"\0" * 4 + b"".join(_s15(v) for v in xyz)


def _tag_lut16(clut: np.ndarray, n_in: int, n_out: int, grid: int) -> bytes:
    """lut16Type with identity input and output curves (2 entries) and the CLUT (uint16, first input slowest)."""
    head = b"mft2" + b"\0" * 4 + struct.pack(">BBBB", n_in, n_out, grid, 0)
    head += b"".join(_s15(v) for v in np.eye(3).ravel()) + struct.pack(">HH", 2, 2)
    ident = struct.pack(">HH", 0, 65535)
    return head + ident * n_in + clut.astype(">u2").tobytes() + ident * n_out


def _encode_lab(lab: np.ndarray) -> np.ndarray:
    enc = np.stack([lab[..., 0] * 652.8, (lab[..., 1] + 128) * 256, (lab[..., 2] + 128) * 256], axis=-1)
    return np.clip(np.round(enc), 0, 65535)


def _decode_lab(enc: np.ndarray) -> np.ndarray:
    return np.stack([enc[..., 0] / 652.8, enc[..., 1] / 256 - 128, enc[..., 2] / 256 - 128], axis=-1)


def build_cmyk_profile(grid_in: int = 9, grid_out: int = 33) -> bytes:
    """The default CMYK output profile (ICC v2, class 'prtr', PCS Lab), deterministic bytes.

    Parameters
    ----------
    grid_in : int
        Grid points per ink of the A2B0 table (CMYK to Lab).
    grid_out : int
        Grid points per PCS axis of the B2A0 table (Lab to CMYK).
    """
    g = np.linspace(0, 1, grid_in)
    cmyk = np.stack(np.meshgrid(g, g, g, g, indexing="ij"), axis=-1).reshape(-1, 4)
    a2b = _encode_lab(cmyk_to_lab_relative(cmyk))
    e = np.linspace(0, 65535, grid_out)
    enc = np.stack(np.meshgrid(e, e, e, indexing="ij"), axis=-1).reshape(-1, 3)
    b2a = np.clip(np.round(separate(_decode_lab(enc)) * 65535), 0, 65535)
    paper = lab_to_xyz(PT1_LAB["paper"])
    tags = [
        (b"desc", _tag_desc("workbench coated PT1 model (ISO 12647-2:2004 aims, Yule-Nielsen)")),
        (b"cprt", _tag_text(COPYRIGHT)),
        (b"wtpt", _tag_xyz(paper)),
        (b"A2B0", _tag_lut16(a2b, 4, 3, grid_in)),
        (b"B2A0", _tag_lut16(b2a, 3, 4, grid_out)),
    ]
    offset = 128 + 4 + 12 * len(tags)
    table, data = struct.pack(">I", len(tags)), b""
    for sig, body in tags:
        table += sig + struct.pack(">II", offset + len(data), len(body))
        data += body + b"\0" * (-len(body) % 4)
    size = offset + len(data)
    header = struct.pack(">I4sI4s4s4s", size, b"\0" * 4, 0x02100000, b"prtr", b"CMYK", b"Lab ")
    header += struct.pack(">6H", 2026, 1, 1, 0, 0, 0) + b"acsp" + b"\0" * 4 + struct.pack(">I", 0)
    header += b"\0" * 4 * 2 + b"\0" * 8 + struct.pack(">I", 0) + b"".join(_s15(v) for v in D50)
    header += b"\0" * 4 + b"\0" * 16
    header += b"\0" * (128 - len(header))
    return header + table + data


def srgb_profile() -> bytes:
    """The sRGB IEC61966-2.1 profile as LittleCMS builds it (Pillow's ImageCms), reproducible.

    LittleCMS stamps the profile with the time it built it and an MD5 profile id over
    that; the date is set to 2026-01-01 and the id to zero ("not computed", allowed by
    ICC.1:2010) so that the same document gives the same bytes.
    """
    from PIL import ImageCms

    data = bytearray(ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes())
    data[24:36] = struct.pack(">6H", 2026, 1, 1, 0, 0, 0)
    data[84:100] = bytes(16)
    return bytes(data)


def profile_info(data: bytes, where: str) -> tuple[str, str]:
    """(colour space, description) of an ICC profile, or an error naming ``where``."""
    import io

    from PIL import ImageCms

    from workbench.errors import WorkbenchError

    try:
        p = ImageCms.ImageCmsProfile(io.BytesIO(data))
    except (OSError, ImageCms.PyCMSError, TypeError, ValueError):
        raise WorkbenchError(f"{where}: not an ICC profile LittleCMS can read") from None
    space = p.profile.xcolor_space.strip()
    if p.profile.profile_description is None:
        desc = ""
    else:
        desc = p.profile.profile_description.strip()
    return space, desc


if __name__ == "__main__":
    DATA.mkdir(exist_ok=True)
    DEFAULT_CMYK_PROFILE.write_bytes(build_cmyk_profile())
    print(f"wrote {DEFAULT_CMYK_PROFILE}")

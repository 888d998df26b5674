"""Colour QA: the photo corrected by the fixture's colour chart against the design's soft proof, in CIEDE2000.

A pure module: arrays in, figures out, no I/O. The steps:

1. :func:`sample_chart`: the chart's 24 patches found by the pose (each patch's corners from
   the fixture definition through the posed camera and its lens), a robust mean of the photo
   inside each patch, away from its edges; patches hidden by the part, clipped (a highlight)
   or too small in the photo are left out.
2. :func:`fit_correction`: the photo's linear RGB to the chart's reference colours (linear
   sRGB, D65, from the CIELAB D50 values), a 3 x 3 matrix or a root-polynomial (Finlayson
   2015) fit with colour-science; its own residual (ΔE00 of the corrected patches against
   their references) says how far the photo can be trusted.
3. :func:`soft_proof`: the design's colours through the output profile (what the press can
   print of them: sRGB → profile → sRGB, LittleCMS), as CIELAB D50.
4. :func:`measure_colour`: the photo warped onto the print, corrected, against the proof,
   per print pixel where the design is locally uniform (a colour edge blurred by the camera
   is geometry, not colour), summarised for the whole print and per region (view, film).

Without a chart in the photo, with the chart in a highlight or a shadow, or with a chart fit
that does not hold, colour is "not measured", with the reason.

Conventions: the photo is 8-bit sRGB-encoded (what a camera's JPEG is); CIELAB is D50 (the
ICC's PCS and the chart's reference); the photo's colours are adapted to D50 by Bradford.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from workbench.camera import Camera
from workbench.mesh.normals import face_normals
from workbench.validate import print_warp

# sRGB (IEC 61966-2-1) primaries, D65, and Bradford adaptation D65 → D50 (as ICC profiles do)
_SRGB_TO_XYZ_D65 = np.array(
    [[0.4124564, 0.3575761, 0.1804375], [0.2126729, 0.7151522, 0.0721750], [0.0193339, 0.1191920, 0.9503041]]
)
_BRADFORD_D65_TO_D50 = np.array(
    [[1.0478112, 0.0228866, -0.0501270], [0.0295424, 0.9904844, -0.0170491], [-0.0092345, 0.0150436, 0.7521316]]
)
_SRGB_TO_XYZ_D50 = _BRADFORD_D65_TO_D50 @ _SRGB_TO_XYZ_D65
D50_WHITE = np.array([0.96422, 1.0, 0.82521])
D50_XY = np.array([0.3457, 0.3585])  # CIE 1931 2°, as colour-science has it
# the ColorChecker Classic's CIELAB D50, reading order (X-Rite, charts after November 2014): what
# workbench.printing.boards.colour_chart_reference derives from colour-science's data (tested
# equal), here so that validate need not import colour-science (0.8 CPU s) to compare a
# fixture's chart with it
CHART_LAB_D50 = np.array(
    [
        [37.54, 14.37, 14.92],
        [64.66, 19.27, 17.50],
        [49.32, -3.82, -22.54],
        [43.46, -12.74, 22.72],
        [54.94, 9.61, -24.79],
        [70.48, -32.26, -0.37],
        [62.73, 35.83, 56.50],
        [39.43, 10.75, -45.17],
        [50.57, 48.64, 16.67],
        [30.10, 22.54, -20.87],
        [71.77, -24.13, 58.19],
        [71.51, 18.24, 67.37],
        [28.37, 15.42, -49.80],
        [54.38, -39.72, 32.27],
        [42.43, 51.05, 28.62],
        [81.80, 2.67, 80.41],
        [50.63, 51.28, -14.12],
        [49.57, -29.71, -28.32],
        [95.19, -1.03, 2.93],
        [81.29, -0.57, 0.44],
        [66.89, -0.75, -0.06],
        [50.76, -0.13, 0.14],
        [35.63, -0.46, -0.48],
        [20.64, 0.07, -0.46],
    ]
)


@dataclass(frozen=True)
class ColourOptions:
    """How colour is measured.

    Attributes
    ----------
    method : {'root-polynomial', 'matrix'}
        The chart fit: Finlayson 2015 root-polynomial of ``degree``, or a 3 x 3 matrix (Cheung 2004).
    degree : int
        Root-polynomial degree (2: 6 terms per channel, 18 coefficients from 24 patches).
    patch_inset : float
        Share of the patch's side left out along each edge before sampling (0.25: its inner half).
    min_patch_px : int
        Fewest photo pixels a patch must give.
    min_patches : int
        Fewest usable patches for a fit.
    saturated : float
        An encoded channel at or above this (0 to 255) in a patch's median is clipped: a highlight.
    min_white_y : float
        The white patch's linear luminance below this: the chart is in shadow (or the photo
        far under-exposed); nothing it says about colour can be trusted.
    max_fit_delta_e : float
        The chart fit's mean ΔE00 above this: the chart is lit unevenly (a highlight or a
        shadow across it) or not where the pose puts it.
    uniform_radius_px : float
        A print pixel is compared when the design is uniform, and the photo shows the part,
        within this radius (photo pixels: beyond the camera's blur and JPEG's blocks); the
        photo is averaged over that window (its noise with it) before it is compared.
    uniform_tol : float
        Uniform: every channel of the design within this many levels (0 to 255) in the window.
    max_samples : int
        Print pixels compared at most (an even subsample beyond: the figures are percentiles).
    shading_delta_l : float
        A mean |ΔL*| at least this large that follows the surface's orientation is called
        shading (a directional light), not ink: see :func:`orientation_shading`.
    """

    method: str = "root-polynomial"
    degree: int = 2
    patch_inset: float = 0.25
    min_patch_px: int = 16
    min_patches: int = 18
    saturated: float = 250.0
    min_white_y: float = 0.08
    max_fit_delta_e: float = 3.0
    uniform_radius_px: float = 4.0
    uniform_tol: float = 6.0
    max_samples: int = 50_000
    shading_delta_l: float = 1.0


# ------------------------------------------------------------------ colour science, vectorised


def srgb_decode(v: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear light; (..., 3) float."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def srgb_encode(v: np.ndarray) -> np.ndarray:
    """Linear light to sRGB-encoded values (not clipped); (..., 3) float."""
    v = np.asarray(v, dtype=np.float64)
    a = np.abs(v)
    return np.sign(v) * np.where(a <= 0.0031308, a * 12.92, 1.055 * a ** (1 / 2.4) - 0.055)


def xyz_to_lab(xyz: np.ndarray, white: np.ndarray = D50_WHITE) -> np.ndarray:
    """CIE XYZ to CIELAB; (..., 3) float."""
    t = np.asarray(xyz, dtype=np.float64) / white
    e = 216 / 24389
    f = np.where(t > e, np.cbrt(t), (24389 / 27 * t + 16) / 116)
    return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]), 200 * (f[..., 1] - f[..., 2])], axis=-1)


def lab_to_xyz(lab: np.ndarray, white: np.ndarray = D50_WHITE) -> np.ndarray:
    """CIELAB to CIE XYZ; (..., 3) float."""
    lab = np.asarray(lab, dtype=np.float64)
    fy = (lab[..., 0] + 16) / 116
    f = np.stack([fy + lab[..., 1] / 500, fy, fy - lab[..., 2] / 200], axis=-1)
    return white * np.where(f**3 > 216 / 24389, f**3, (116 * f - 16) / (24389 / 27))


def mat3(x: np.ndarray, M: np.ndarray) -> np.ndarray:
    """``x @ M.T`` for (..., 3) x: three scaled columns rather than BLAS, whose threads spin
    idle on a loaded machine (seen: 0.8 s for 400k colours, 10 ms this way)."""
    x = np.asarray(x, dtype=np.float64)
    return x[..., 0:1] * M[:, 0] + x[..., 1:2] * M[:, 1] + x[..., 2:3] * M[:, 2]


def linear_srgb_to_lab(rgb: np.ndarray) -> np.ndarray:
    """Linear sRGB (D65) to CIELAB D50 (Bradford); (..., 3) float."""
    return xyz_to_lab(mat3(rgb, _SRGB_TO_XYZ_D50))


def lab_to_linear_srgb(lab: np.ndarray) -> np.ndarray:
    """CIELAB D50 to linear sRGB (D65, Bradford), not clipped; (..., 3) float."""
    return mat3(lab_to_xyz(lab), np.linalg.inv(_SRGB_TO_XYZ_D50))


def delta_e00(lab1: np.ndarray, lab2: np.ndarray) -> np.ndarray:
    """CIEDE2000 colour difference (Sharma, Wu, Dalal 2005; kL = kC = kH = 1); (...,) float.

    The same figures as ``colour.delta_E(..., method='CIE 2000')``, several times faster.
    """
    L1, a1, b1 = np.moveaxis(np.asarray(lab1, dtype=np.float64), -1, 0)
    L2, a2, b2 = np.moveaxis(np.asarray(lab2, dtype=np.float64), -1, 0)
    C1, C2 = np.hypot(a1, b1), np.hypot(a2, b2)
    Cm7 = ((C1 + C2) / 2) ** 7
    G = 0.5 * (1 - np.sqrt(Cm7 / (Cm7 + 25.0**7)))
    a1p, a2p = (1 + G) * a1, (1 + G) * a2
    C1p, C2p = np.hypot(a1p, b1), np.hypot(a2p, b2)
    h1p = np.degrees(np.arctan2(b1, a1p)) % 360
    h2p = np.degrees(np.arctan2(b2, a2p)) % 360
    dLp, dCp = L2 - L1, C2p - C1p
    dh = h2p - h1p
    dh = np.where(dh > 180, dh - 360, np.where(dh < -180, dh + 360, dh))
    dh = np.where(C1p * C2p == 0, 0.0, dh)
    dHp = 2 * np.sqrt(C1p * C2p) * np.sin(np.radians(dh) / 2)
    Lpm, Cpm = (L1 + L2) / 2, (C1p + C2p) / 2
    hs = h1p + h2p
    hpm = np.where(np.abs(h1p - h2p) > 180, np.where(hs < 360, hs / 2 + 180, hs / 2 - 180), hs / 2)
    hpm = np.where(C1p * C2p == 0, hs, hpm)
    T = (
        1
        - 0.17 * np.cos(np.radians(hpm - 30))
        + 0.24 * np.cos(np.radians(2 * hpm))
        + 0.32 * np.cos(np.radians(3 * hpm + 6))
        - 0.20 * np.cos(np.radians(4 * hpm - 63))
    )
    dtheta = 30 * np.exp(-(((hpm - 275) / 25) ** 2))
    Cpm7 = Cpm**7
    RC = 2 * np.sqrt(Cpm7 / (Cpm7 + 25.0**7))
    SL = 1 + 0.015 * (Lpm - 50) ** 2 / np.sqrt(20 + (Lpm - 50) ** 2)
    SC = 1 + 0.045 * Cpm
    SH = 1 + 0.015 * Cpm * T
    RT = -np.sin(np.radians(2 * dtheta)) * RC
    return np.sqrt((dLp / SL) ** 2 + (dCp / SC) ** 2 + (dHp / SH) ** 2 + RT * (dCp / SC) * (dHp / SH))


# ------------------------------------------------------------------ the chart in the photo


@dataclass(frozen=True)
class ChartSample:
    """The chart's patches as the photo shows them.

    Attributes
    ----------
    rgb : (24, 3) float
        Robust mean of each patch, sRGB-encoded 0 to 255 (NaN: not usable).
    pixels : (24,) int
        Photo pixels each mean is over.
    usable : (24,) bool
    why : list of str
        Per patch, why it is not usable ('' when it is).
    quads : (24, 4, 2) float
        Patch corners in the photo (through the lens), pixels.
    """

    rgb: np.ndarray
    pixels: np.ndarray
    usable: np.ndarray
    why: list
    quads: np.ndarray


def project_points(cam: Camera, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World points (n, 3) through the posed camera and its lens: pixels (n, 2) and depth (n,) mm.

    :func:`workbench.validate.print_warp.project_through_lens` (one compiled pass: a print grid's
    1.4 million points in tens of milliseconds, where ``cv2.projectPoints`` takes seconds).
    """
    from workbench.validate.print_warp import project_through_lens

    _, z, lens = project_through_lens(cam, np.ascontiguousarray(X, dtype=np.float64))
    return lens, z


def sample_chart(
    photo: np.ndarray,
    cam: Camera,
    chart: dict,
    part_depth: np.ndarray | None = None,
    opts: ColourOptions = ColourOptions(),
) -> ChartSample:
    """The chart's patches in the photo, each a robust mean inside its projected quad away from its edges.

    Parameters
    ----------
    photo : (H, W, 3) uint8
        sRGB-encoded photo.
    cam : Camera
        Its posed camera, with the lens.
    chart : dict
        The fixture's ``colour_chart`` (``patches[k].corners_mesh_mm``).
    part_depth : (H, W) float, optional
        Depth buffer of the part in the undistorted camera (+inf: no part): a patch the
        part hides, even partly, is left out.
    opts : ColourOptions

    Returns
    -------
    ChartSample
    """
    H, W = photo.shape[:2]
    corners = np.array([p["corners_mesh_mm"] for p in chart["patches"]], dtype=np.float64)  # (24, 4, 3)
    n = len(corners)
    # the patch's inner part: corners pulled towards the centre by the inset on each side
    centre = corners.mean(axis=1, keepdims=True)
    inner = centre + (1 - 2 * opts.patch_inset) * (corners - centre)
    quads, z = project_points(cam, inner.reshape(-1, 3))
    quads, z = quads.reshape(n, 4, 2), z.reshape(n, 4)
    rgb = np.full((n, 3), np.nan)
    pixels = np.zeros(n, dtype=np.int64)
    why = [""] * n
    for k in range(n):
        q = quads[k]
        if (z[k] <= 0).any() or not np.isfinite(q).all():
            why[k] = "behind the camera"
            continue
        lo = np.floor(q.min(axis=0)).astype(int)
        hi = np.ceil(q.max(axis=0)).astype(int)
        if lo[0] < 0 or lo[1] < 0 or hi[0] > W - 1 or hi[1] > H - 1:
            why[k] = "outside the photo"
            continue
        mask = np.zeros((hi[1] - lo[1] + 1, hi[0] - lo[0] + 1), np.uint8)
        # pixel centres at integers (the workbench's convention, and cv2's for polygons)
        cv2.fillConvexPoly(mask, np.round((q - lo) * 16).astype(np.int32), 1, lineType=cv2.LINE_8, shift=4)
        inside = mask.astype(bool)
        if part_depth is not None:
            zz = z[k].mean()
            hidden = part_depth[lo[1] : hi[1] + 1, lo[0] : hi[0] + 1] < zz
            if (hidden & inside).any():
                why[k] = "hidden by the part"
                continue
        px = photo[lo[1] : hi[1] + 1, lo[0] : hi[0] + 1][inside].astype(np.float64)
        if len(px) < opts.min_patch_px:
            why[k] = f"{len(px)} pixels in the photo, fewer than {opts.min_patch_px}"
            continue
        med = np.median(px, axis=0)
        if (med >= opts.saturated).any():
            why[k] = "clipped (a highlight)"
            continue
        # robust mean: the pixels within 3 MADs of the median (specks, a stray reflection)
        mad = np.median(np.abs(px - med), axis=0) * 1.4826 + 0.5
        keep = (np.abs(px - med) <= 3 * mad).all(axis=1)
        rgb[k] = px[keep].mean(axis=0)
        pixels[k] = int(keep.sum())
    usable = np.isfinite(rgb[:, 0])
    return ChartSample(rgb, pixels, usable, why, quads)


def _spow(x: np.ndarray, p: float) -> np.ndarray:
    """Sign-preserving power (a linear value slightly below 0 from noise stays a small negative)."""
    return np.sign(x) * np.abs(x) ** p


def expansion(rgb: np.ndarray, method: str, degree: int) -> np.ndarray:
    """The terms a correction is linear in: (n, 3) linear RGB to (n, k).

    'Cheung 2004' with 3 terms: R, G, B (a 3 x 3 matrix). 'Finlayson 2015' root-polynomials of
    ``degree`` 1 to 3 (3, 6 or 13 terms): every term is of degree one in the light, so the fit
    is exposure-invariant. The terms and their order are colour-science's
    (``polynomial_expansion_Finlayson2015``), so its matrices and these are interchangeable.
    """
    rgb = np.asarray(rgb, dtype=np.float64)
    R, G, B = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    if method == "Cheung 2004" or degree == 1:
        return rgb
    if method != "Finlayson 2015" or degree not in (2, 3):
        raise ValueError(f"no expansion for {method!r} of degree {degree}")
    terms = [R, G, B, _spow(R * G, 1 / 2), _spow(G * B, 1 / 2), _spow(R * B, 1 / 2)]
    if degree == 3:
        terms += [
            _spow(R * G**2, 1 / 3),
            _spow(G * B**2, 1 / 3),
            _spow(R * B**2, 1 / 3),
            _spow(G * R**2, 1 / 3),
            _spow(B * G**2, 1 / 3),
            _spow(B * R**2, 1 / 3),
            _spow(R * G * B, 1 / 3),
        ]
    return np.stack(terms, axis=-1)


@dataclass(frozen=True)
class Correction:
    """A fitted colour correction: the photo's linear RGB to linear sRGB (D65) as the chart says.

    Attributes
    ----------
    ccm : (3, k) float
        The correction matrix on the ``method``'s terms (:func:`expansion`), as colour-science
        has it (``colour.matrix_colour_correction``).
    method : str
        'Finlayson 2015' (root-polynomial) or 'Cheung 2004' (3 x 3 matrix), colour-science's names.
    degree : int
    fit_delta_e00 : (24,) float
        ΔE00 of each corrected patch against its reference (NaN: not used).
    """

    ccm: np.ndarray
    method: str
    degree: int
    fit_delta_e00: np.ndarray

    def apply(self, linear_rgb: np.ndarray) -> np.ndarray:
        """Correct linear RGB (n, 3) to linear sRGB (n, 3)."""
        e = expansion(linear_rgb, self.method, self.degree)
        # the terms' weighted sums, column by column: no BLAS (its threads spin on a loaded machine)
        out = np.zeros(e.shape[:-1] + (3,))
        for k in range(e.shape[-1]):
            out += e[..., k : k + 1] * self.ccm[:, k]
        return out


def fit_correction(sample: ChartSample, reference_lab: np.ndarray, opts: ColourOptions = ColourOptions()) -> Correction:
    """Fit the photo's linear RGB of the usable patches to the chart's reference colours, least squares.

    The same fit as colour-science's ``colour.matrix_colour_correction`` (Moore-Penrose least
    squares on :func:`expansion`'s terms; tests/test_colour.py compares them), done here in a
    few lines: importing colour-science takes about 0.8 CPU s, a sixth of a photo's budget.

    Parameters
    ----------
    sample : ChartSample
    reference_lab : (24, 3) float
        The patches' CIELAB D50.
    opts : ColourOptions

    Returns
    -------
    Correction
    """
    ok = sample.usable
    measured = srgb_decode(sample.rgb[ok] / 255.0)
    target = lab_to_linear_srgb(reference_lab[ok])
    method, degree = ("Cheung 2004", 1) if opts.method == "matrix" else ("Finlayson 2015", opts.degree)
    ccm = np.linalg.lstsq(expansion(measured, method, degree), target, rcond=None)[0].T
    corr = Correction(ccm, method, degree, np.full(len(ok), np.nan))
    fit = np.full(len(ok), np.nan)
    fit[ok] = delta_e00(linear_srgb_to_lab(corr.apply(measured)), reference_lab[ok])
    return Correction(ccm, method, degree, fit)


# ------------------------------------------------------------------ the design's soft proof


def proof_srgb(rgb: np.ndarray, output_profile: bytes) -> np.ndarray:
    """The design's sRGB as the press reproduces it: sRGB → output profile → sRGB (LittleCMS); uint8.

    Relative colorimetric with black point compensation into the profile (what ``workbench
    pdf --cmyk`` does), relative colorimetric back: colours out of the press's gamut come
    back as what it can print.
    """
    import io

    from PIL import Image, ImageCms

    rgb = np.asarray(rgb)
    srgb = ImageCms.createProfile("sRGB")
    t = ImageCms.buildProofTransform(
        srgb,
        srgb,
        ImageCms.ImageCmsProfile(io.BytesIO(output_profile)),
        "RGB",
        "RGB",
        renderingIntent=ImageCms.Intent.RELATIVE_COLORIMETRIC,
        proofRenderingIntent=ImageCms.Intent.RELATIVE_COLORIMETRIC,
        flags=ImageCms.Flags.SOFTPROOFING | ImageCms.Flags.BLACKPOINTCOMPENSATION,
    )
    flat = np.ascontiguousarray(rgb.reshape(1, -1, 3).astype(np.uint8))
    return np.asarray(ImageCms.applyTransform(Image.fromarray(flat), t)).reshape(rgb.shape)


def soft_proof(rgb: np.ndarray, output_profile: bytes | None) -> np.ndarray:
    """The design's colours as the press prints them, CIELAB D50.

    Parameters
    ----------
    rgb : (..., 3) uint8
        The design's sRGB.
    output_profile : bytes or None
        The output ICC profile (:func:`proof_srgb`); None: the sRGB as it is.

    Returns
    -------
    (..., 3) float
    """
    rgb = np.asarray(rgb)
    if output_profile is not None:
        rgb = proof_srgb(rgb, output_profile)
    return linear_srgb_to_lab(srgb_decode(rgb / 255.0))


# ------------------------------------------------------------------ the measurement


def uniform_design(reference: np.ndarray, radius: int, tol: float) -> np.ndarray:
    """Print pixels whose design is uniform within ``radius`` (every channel within ``tol`` levels); (rows, cols)."""
    k = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * radius + 1, 2 * radius + 1))
    ref = np.ascontiguousarray(reference)
    # per channel, the window's range (saturating uint8), then the channels' largest: OpenCV
    # throughout (numpy's reduction over the channel axis took most of the measurement's time)
    r, g, b = cv2.split(cv2.subtract(cv2.dilate(ref, k), cv2.erode(ref, k)))
    return cv2.max(cv2.max(r, g), b) <= tol


MAX_WINDOW_PX = 48  # widest window radius, grid pixels: beyond it the photo is too coarse to judge colour there


def local_scale(cam: Camera, surface_mm: np.ndarray | None, uniform, shape) -> np.ndarray:
    """Photo pixels per grid pixel at every grid pixel, along the print's more foreshortened axis; (rows, cols).

    From the surface points projected into the photo when given, else ``uniform``: one
    figure everywhere, or a (rows, cols) array of them (``warp_to_print``'s footprint, which
    is this same figure, already computed).
    """
    if surface_mm is None:
        return np.broadcast_to(np.asarray(uniform, dtype=np.float64), shape)
    rows, cols = shape
    on = np.isfinite(surface_mm[..., 0])
    xy = np.full((rows, cols, 2), np.nan)
    xy[on] = project_points(cam, surface_mm[on])[0]
    with np.errstate(invalid="ignore"):
        ax = np.linalg.norm(np.gradient(xy, axis=1), axis=2)
        ay = np.linalg.norm(np.gradient(xy, axis=0), axis=2)
        s = np.minimum(ax, ay)  # a square window must reach far enough along both
    return np.where(np.isfinite(s), s, np.nan)


def compared_pixels(scored, reference, scale, opts: ColourOptions) -> np.ndarray:
    """Which grid pixels to compare, and the window each one's photo is averaged over.

    A pixel's window spans ``opts.uniform_radius_px`` photo pixels (its radius in grid
    pixels from the local scale, rounded up to one of a few levels). A pixel is compared
    when the whole window is scored (no outline, fold or defect mixing in other colours;
    inside the grid) and the design is uniform over it: the photo's mean there
    (:func:`window_means`) is then the print's colour, its noise averaged down.

    Returns
    -------
    radius : (rows, cols) int16
        The window's radius, grid pixels; 0 where the pixel is not compared.
    """
    radius = np.zeros(scored.shape, np.int16)
    rows = np.flatnonzero(scored.any(axis=1))
    cols = np.flatnonzero(scored.any(axis=0))
    if len(rows) == 0:
        return radius
    # only the scored area and the widest window around it: every window of a scored pixel lies
    # inside, so the crop changes no figure (a photo sees a part of the print: about half here)
    m = MAX_WINDOW_PX + 1
    crop = (
        slice(max(rows[0] - m, 0), min(rows[-1] + m + 1, scored.shape[0])),
        slice(max(cols[0] - m, 0), min(cols[-1] + m + 1, scored.shape[1])),
    )
    scored, reference = scored[crop], reference[crop]
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.ceil(opts.uniform_radius_px / np.asarray(scale)[crop][scored])
    need = np.where(np.isfinite(need), np.maximum(need, 1), np.inf)
    fin = need[np.isfinite(need)]
    levels = sorted({int(v) for v in np.unique(np.ceil(1.25 ** np.ceil(np.log(fin) / np.log(1.25))))})
    levels = [r for r in levels if r <= MAX_WINDOW_PX]
    need_map = np.full(scored.shape, np.inf, np.float32)
    need_map[scored] = need
    out = radius[crop]
    sc = scored.astype(np.uint8)
    lower = 0
    for r in levels:
        here = (need_map > lower) & (need_map <= r)
        lower = r
        if not here.any():
            continue
        window = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * r + 1, 2 * r + 1))
        # beyond the grid counts as not scored: every window lies inside it
        inside = cv2.erode(sc, window, borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)
        out[here & inside & uniform_design(reference, r, opts.uniform_tol)] = r
    return radius


def window_means(img: np.ndarray, ii: np.ndarray, jj: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The mean of ``img`` (rows, cols, 3) over the square window of radius ``r`` (n,) about each (ii, jj) (n,).

    From one integral image (exact sums: 8-bit values, int64), so that only the pixels
    compared cost anything; every window must lie inside the image. Returns (n, 3) float.
    """
    S = cv2.integral(np.ascontiguousarray(img), sdepth=cv2.CV_64F)
    i0, i1, j0, j1 = ii - r, ii + r + 1, jj - r, jj + r + 1
    total = S[i1, j1] - S[i0, j1] - S[i1, j0] + S[i0, j0]
    return total / ((2 * r + 1) ** 2)[:, None]


def delta_e_figures(d: np.ndarray) -> dict:
    """A ΔE00 sample's mean, median, p95, max and size (all None but the size when empty)."""
    if len(d) == 0:
        return {"mean": None, "p95": None, "max": None, "pixels": 0}
    return {
        "mean": round(float(d.mean()), 3),
        "median": round(float(np.median(d)), 3),
        "p95": round(float(np.percentile(d, 95)), 3),
        "max": round(float(d.max()), 3),
        "pixels": int(len(d)),
    }


def not_measured(reason: str, **more) -> dict:
    """The ``colour`` entry of a photo whose colour could not be measured."""
    return {"measured": False, "reason": f"colour not measured: {reason}", **more}


def measure_colour(
    photo: np.ndarray,
    cam: Camera,
    chart: dict | None,
    warped: np.ndarray,
    scored: np.ndarray,
    reference: np.ndarray,
    regions: dict[str, np.ndarray] | None = None,
    output_profile: bytes | None = None,
    part_depth: np.ndarray | None = None,
    surface_mm: np.ndarray | None = None,
    photo_px_per_grid_px: float | np.ndarray = 1.0,
    normal: np.ndarray | None = None,
    opts: ColourOptions = ColourOptions(),
) -> tuple[dict, np.ndarray | None]:
    """CIEDE2000 between the photographed decoration, corrected by the chart, and the design's soft proof.

    Parameters
    ----------
    photo : (H, W, 3) uint8
        sRGB-encoded photo.
    cam : Camera
        Its posed camera (the pose validate measured), with the lens.
    chart : dict or None
        The fixture's ``colour_chart``; None: not measured.
    warped : (rows, cols, 3) uint8
        The photo on the print's analysis grid (:func:`workbench.validate.print_warp.warp_to_print`).
    scored : (rows, cols) bool
        Grid pixels the photo shows well enough to judge (state FULL, outside defects).
    reference : (rows, cols, 3) uint8
        The design on the same grid (``PrintGrid.reference``).
    regions : dict of str to (rows, cols) bool, optional
        Named regions to summarise alone (``"view logo"``, ``"film cheek"``, ...).
    output_profile : bytes or None
        See :func:`soft_proof`.
    part_depth : (H, W) float, optional
        The part's depth buffer in the photo (:func:`workbench.validate.print_warp.photo_buffers`):
        patches the part hides are left out.
    surface_mm : (rows, cols, 3) float, optional
        The surface point under each grid pixel (``PrintGrid.X``, NaN off the part): the
        photo's local scale on the print then sets each pixel's window (a fine logo seen
        from afar needs a wider one, in print pixels, than the same print seen close up).
    photo_px_per_grid_px : float or (rows, cols) float
        Without ``surface_mm``: how many photo pixels one grid pixel spans, everywhere
        (``warp_to_print``'s scale) or at each grid pixel (its footprint).
    normal : (rows, cols, 3) float, optional
        Unit outward surface normal under each grid pixel (``PrintGrid.normal``: interpolated
        from the vertex normals, as both renderers and a smooth real part shade; NaN off the
        part). With it, the lightness difference that follows the surface's orientation is
        split off as shading (:func:`orientation_shading`).
    opts : ColourOptions

    Returns
    -------
    colour : dict
        JSON-ready. ``measured`` (bool) and ``reason`` when not; else ``delta_e00`` {mean,
        median, p95, max, pixels}, ``delta_e00_chromatic`` (the same with the photo's L* set
        to the proof's: what remains once lightness, which shading also moves, is left
        aside), ``lightness`` {mean_delta_l, mean_abs_delta_l} (photo minus proof),
        ``chart_fit_delta_e00`` (mean over the usable patches) and ``chart`` (method,
        patches used, fit max, which were left out and why), ``regions`` {name: figures};
        with the normals ``shading`` (:func:`orientation_shading`).
    delta_e_map : (rows, cols) float32 or None
        The ΔE00 the verdict judges per grid pixel (with the shading out under a directional
        light; NaN: not compared), for a colour-difference picture and the part's colour.
    """
    if chart is None:
        return not_measured("the fixture has no colour chart (fixture.json: colour_chart)"), None
    sample = sample_chart(photo, cam, chart, part_depth, opts)
    names = [p["name"] for p in chart["patches"]]
    left_out = {names[k]: sample.why[k] for k in range(len(names)) if not sample.usable[k]}
    chart_info = {"kind": chart.get("kind"), "patches_used": int(sample.usable.sum()), "left_out": left_out}
    reasons = set(left_out.values())
    if sample.usable.sum() < opts.min_patches:
        if reasons & {"outside the photo", "behind the camera"}:
            why = "the colour chart is not in the photo"
        elif "clipped (a highlight)" in reasons:
            why = "the colour chart is in a highlight (patches clipped)"
        else:
            why = "too few of the chart's patches are usable"
        return not_measured(
            f"{why}: {int(sample.usable.sum())} of {len(names)} patches usable, {opts.min_patches} needed",
            chart=chart_info,
        ), None
    white = next((k for k, nm in enumerate(names) if nm.startswith("white")), None)
    if white is not None and sample.usable[white]:
        y_white = float(srgb_decode(sample.rgb[white] / 255.0) @ _SRGB_TO_XYZ_D65[1])
        chart_info["white_patch_linear_y"] = round(y_white, 4)
        if y_white < opts.min_white_y:
            return not_measured(
                f"the colour chart is in shadow or the photo under-exposed (white patch at linear Y {y_white:.3f}, "
                f"under {opts.min_white_y:g})",
                chart=chart_info,
            ), None
    ref_lab = np.array([p["lab_d50"] for p in chart["patches"]], dtype=np.float64)
    if len(ref_lab) == 24 and not np.allclose(ref_lab, CHART_LAB_D50, atol=0.05):
        chart_info["reference"] = "the fixture's own values"
    corr = fit_correction(sample, ref_lab, opts)
    fit = corr.fit_delta_e00[sample.usable]
    chart_info.update(method=corr.method, degree=corr.degree if corr.method == "Finlayson 2015" else None)
    chart_info["fit_max_delta_e00"] = round(float(fit.max()), 3)
    fit_mean = round(float(fit.mean()), 3)
    if fit_mean > opts.max_fit_delta_e:
        return not_measured(
            f"the chart fit does not hold (mean ΔE00 {fit_mean:.2f} over its patches, more than "
            f"{opts.max_fit_delta_e:g}): the chart is lit unevenly (a highlight or a shadow across it) or not "
            "where the pose puts it",
            chart=chart_info,
            chart_fit_delta_e00=fit_mean,
        ), None

    radius = compared_pixels(scored, reference, local_scale(cam, surface_mm, photo_px_per_grid_px, scored.shape), opts)
    use = radius > 0
    idx = np.flatnonzero(use)
    if len(idx) > opts.max_samples:  # an even subsample: deterministic, spread over the print
        idx = idx[np.linspace(0, len(idx) - 1, opts.max_samples).round().astype(np.int64)]
    if len(idx) == 0:
        return not_measured("no uniform area of the decoration is seen", chart=chart_info), None
    ref_px = reference.reshape(-1, 3)[idx]
    ii, jj = np.divmod(idx, scored.shape[1])
    photo_px = window_means(warped, ii, jj, radius.reshape(-1)[idx].astype(np.int64))
    proof = soft_proof(ref_px, output_profile)
    got = linear_srgb_to_lab(corr.apply(srgb_decode(photo_px / 255.0)))
    de = delta_e00(proof, got)
    chromatic = delta_e00(proof, np.column_stack([proof[:, 0], got[:, 1:]]))
    dL = got[:, 0] - proof[:, 0]
    out = {
        "measured": True,
        "delta_e00": delta_e_figures(de),
        "delta_e00_chromatic": delta_e_figures(chromatic),
        "lightness": {
            "mean_delta_l": round(float(dL.mean()), 3),
            "mean_abs_delta_l": round(float(np.abs(dL).mean()), 3),
        },
        "chart_fit_delta_e00": fit_mean,
        "chart": chart_info,
        "soft_proof": "output profile" if output_profile is not None else "sRGB as designed",
        "compared_share": round(float(use.sum() / max(scored.sum(), 1)), 4),
        "compared_pixels": int(use.sum()),
    }
    judged = de
    if normal is not None:
        # (the normal the surface is shaded by: interpolated over each triangle, not the triangle's
        # own, whose facets turn 10° from it on a 6,000-triangle cow and whose shading then reads as
        # ink: a glossy Mitsuba cow's perfect print judged 2.95 and 3.19 ΔE00 with the facets' normals,
        # 1.35 and 1.98 with these)
        normals = np.nan_to_num(normal.reshape(-1, 3)[idx].astype(np.float64))
        out["shading"], without = orientation_shading(proof, got, normals, chart_normal(chart, cam), de, opts)
        if out["shading"]["directional"]:
            judged = without  # (what the verdict judges: see workbench.validate.rule.colour_verdict)
    de_map = np.full(scored.shape, np.nan, dtype=np.float32)
    de_map.reshape(-1)[idx] = judged
    if regions:
        out["regions"] = {name: delta_e_figures(de[mask.reshape(-1)[idx]]) for name, mask in regions.items()}
    return out, de_map


def chart_normal(chart: dict, cam: Camera) -> np.ndarray:
    """The chart's unit normal, on the side the camera sees; (3,) float."""
    c = np.asarray([p["corners_mesh_mm"] for p in chart["patches"]], dtype=np.float64).reshape(-1, 3)
    centre = c.mean(axis=0)
    # the plane through every corner: the smallest singular vector of the centred corners
    n = np.linalg.svd(c - centre, full_matrices=False)[2][-1]
    return n if n @ (cam.center - centre) > 0 else -n


# cells of the normal's components for the lightness that follows the orientation: 0.1 is about
# 6° on the sphere, finer than a lamp's shading changes by more than its terminator; a cell's
# median needs ORIENTATION_MIN_SAMPLES (fewer: none, the linear model alone)
ORIENTATION_CELL = 0.1
ORIENTATION_MIN_SAMPLES = 30


def orientation_median(values: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Each sample's median of ``values`` over its cell of normals (ORIENTATION_CELL); (n,) float.

    Parameters
    ----------
    values : (n,) float
    normals : (n, 3) float
        Unit normals.

    Returns
    -------
    (n,) float64
        0 in a cell of fewer than ORIENTATION_MIN_SAMPLES samples.
    """
    out = np.zeros(len(values))
    if len(values) == 0:
        return out
    cells = np.floor(np.asarray(normals) / ORIENTATION_CELL).astype(np.int64)
    _, inverse, counts = np.unique(cells, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    order = np.argsort(inverse, kind="stable")
    bounds = np.concatenate([[0], np.cumsum(counts)])
    sorted_values = np.asarray(values, np.float64)[order]
    medians = np.zeros(len(counts))
    for c in np.flatnonzero(counts >= ORIENTATION_MIN_SAMPLES):
        medians[c] = np.median(sorted_values[bounds[c] : bounds[c + 1]])
    return medians[inverse]


def take_light_out(lab: np.ndarray, h: np.ndarray) -> np.ndarray:
    """CIELAB (n, 3) with a light of ``ln(k) / 3 = h`` (n,) taken out of X, Y and Z alike.

    A factor k on XYZ scales L* + 16, a* and b* by k^(1/3): taken out of L* alone, a shaded
    saturated ink kept a* and b* as shaded (on perfect renders under a directional lamp 0.1 to
    1.6 ΔE00 of "ink", and a print off in a* and b* read weaker than it is).
    """
    return xyz_to_lab(lab_to_xyz(lab) * np.exp(-3.0 * h)[:, None])


def orientation_shading(
    proof: np.ndarray,
    got: np.ndarray,
    normals: np.ndarray,
    n_chart: np.ndarray,
    de: np.ndarray,
    opts: ColourOptions = ColourOptions(),
) -> tuple[dict, np.ndarray]:
    """How much of the difference is lightness that follows the surface's orientation: shading.

    The chart corrects the photo for the light the chart receives. Under even, diffuse
    light every surface receives that light; under a directional one a surface turned
    towards the lamp receives more: its X, Y and Z look larger by a factor ``k(n)``, which
    the camera cannot tell from ink density. A factor on the light is a factor ``k`` on Y,
    so ``ln((L* + 16) / (L*_proof + 16)) = ln(k) / 3`` whatever the colour; it is fitted,
    least squares, as ``a + b · (n - mean n)`` over the compared pixels, plus what that leaves
    at the pixel's orientation, the median over its cell of normals (:func:`orientation_median`).
    The shading at a pixel is that light less the linear model's at the chart's normal: nothing
    where the surface faces as the chart does (a surface of one orientation, such as a flat
    film, shows none: there the camera cannot separate shading from ink at all); its mean |ΔL*|
    says whether the light is directional. Under even light an ink that is too light or dark
    moves every surface alike and stays. Under a directional light the level itself (the part's
    light where it faces as the chart does) is left free, the print's overall lightness not
    judged: see the comment in the code for what it was measured on. The factor is taken out
    of X, Y and Z, so out of L*, a* and b* alike (:func:`take_light_out`). (Second-order
    spherical harmonics of the normal in place of the linear model, or a lamp's clamped cosine
    with them, left more on perfect renders of the cow under a directional lamp: 4.7 to 7.6
    ΔE00 against 3.2 to 4.5, before the cells.)

    Parameters
    ----------
    proof, got : (n, 3) float
        The soft proof and the corrected photo, CIELAB D50.
    normals : (n, 3) float
        Unit surface normals (outward) at those pixels.
    n_chart : (3,) float
        The chart's normal (:func:`chart_normal`).
    de : (n,) float
        ΔE00 of the pixels.
    opts : ColourOptions

    Returns
    -------
    summary : dict
        ``mean_abs_delta_l`` (ΔL* that follows the orientation, mean over the pixels),
        ``delta_e00`` (the figures with it taken out of L*, a* and b*), ``share`` (of the mean
        ΔE00 that it is), ``directional`` (``mean_abs_delta_l`` at least
        ``opts.shading_delta_l``), ``level`` (``judged``: false under a directional light;
        ``log_ratio``: the linear model's ``ln(k) / 3`` at the chart's normal; ``delta_l``: the
        mean ΔL* the print would show with that level, beyond what is judged) and a ``note``.
    without : (n,) float
        Each pixel's ΔE00 with the shading taken out.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.log(np.maximum(got[:, 0] + 16.0, 1.0) / np.maximum(proof[:, 0] + 16.0, 1.0))
    dn = normals - normals.mean(axis=0)
    A = np.column_stack([np.ones(len(g)), dn])
    # the normal equations without BLAS (whose threads spin on a loaded machine); a part of one
    # orientation has zero columns, which lstsq's cut-off leaves at zero slope
    AtA = np.einsum("ij,ik->jk", A, A)
    Atg = np.einsum("ij,i->j", A, g)
    coef = np.linalg.lstsq(AtA, Atg, rcond=1e-9)[0]
    # lightness that follows the orientation is shading whatever its shape: what the linear model
    # leaves, as the median over each cell of normals, is shading too (a lamp's clamped cosine and
    # its ambient are no linear function: on perfect renders of the cow it left 3.2 to 4.5 ΔE00)
    left = g - A @ coef
    s = A @ coef + orientation_median(left, normals)  # ln(k) / 3 at each pixel's orientation
    # the linear model's value at the chart's normal: the light there against the chart's
    level = float(coef[0] + (np.asarray(n_chart) - normals.mean(axis=0)) @ coef[1:])
    anchored = take_light_out(got, s - level)
    shade_dl = got[:, 0] - anchored[:, 0]
    mean_abs = float(np.abs(shade_dl).mean())
    directional = mean_abs >= opts.shading_delta_l
    # under a directional light the part's light where it faces as the chart does is not the
    # chart's: a cast shadow, a sheen, the lamp's falloff between chart and part. Over seven
    # perfect photos under a lamp (of the cow, the lily and the face, both renderers) the linear
    # model put that level at -0.096 to +0.027 of ln(k) / 3, the pixels that face as the chart
    # does at -0.119 to +0.174 (shadows, sheen): 4.3 to 11.8 ΔE00 of "ink" on perfect prints,
    # where neither held. The print's overall lightness is then not told from the light: the level is
    # left free (the colours against each other, and their chroma, are judged), and what it
    # would make of the lightness is reported (``level``)
    without_lab = take_light_out(got, s) if directional else anchored
    without = delta_e00(proof, without_lab)
    share = max(0.0, 1.0 - float(without.mean()) / float(de.mean())) if de.mean() > 0 else 0.0
    note = (
        f"{100 * share:.0f} % of the mean ΔE00 is lightness that follows the surface's orientation "
        f"(mean |ΔL*| {mean_abs:.2f}): shading under a directional light, which a camera cannot tell from ink; "
        "the print's overall lightness is not judged under it; measure colour under even, diffuse light (a light "
        "tent or viewing booth)"
        if directional
        else "no lightness difference follows the surface's orientation: the light is even"
    )
    summary = {
        "mean_abs_delta_l": round(mean_abs, 3),
        "delta_e00": delta_e_figures(without),
        "share": round(share, 4),
        "directional": bool(directional),
        "level": {
            "judged": not directional,
            "log_ratio": round(level, 4),
            "delta_l": round(float((anchored[:, 0] - without_lab[:, 0]).mean()), 3),
        },
        "note": note,
    }
    return summary, without


def photo_colour(
    photo: np.ndarray,
    cam: Camera,
    design,
    grid,
    warped: np.ndarray,
    state: np.ndarray,
    footprint: np.ndarray,
    depth: np.ndarray,
    output_profile: bytes | None = None,
    opts: ColourOptions = ColourOptions(),
    reference: np.ndarray | None = None,
) -> tuple[dict, np.ndarray | None, np.ndarray | None]:
    """:func:`measure_colour` on what validate has of a photo once its dense analysis is done.

    Parameters
    ----------
    photo, cam
        The photo and its posed camera.
    design : workbench.design_dir.Design
        The part (``V``, ``F``: its normals where the grid has none, for shading under a
        directional light), its fixture (``colour_chart``, if any), its views (regions ``"view NAME"`` by
        the grid's owner) and films (design.json's ``films``, ``atlas_px``, ``width_px``,
        ``height_px`` in print pixels: regions ``"film NAME"``).
    grid : workbench.validate.print_warp.PrintGrid
    warped, footprint : arrays
        :func:`workbench.validate.print_warp.warp_to_print`'s photo on the grid and its footprint.
    state : (rows, cols) uint8
        The dense analysis's state per grid pixel: the measured pixels outside defects,
        highlights and shadows are compared.
    depth : (H, W) float
        The part's depth buffer in the photo.
    output_profile : bytes or None
        The soft proof's output profile (None: the design's sRGB as it is).
    opts : ColourOptions
    reference : (rows, cols, 3) uint8, optional
        The print on the grid where the film lies (moved by its fitted placement:
        :func:`workbench.validate.placement.placed_print`); default ``grid.reference``.

    Returns
    -------
    colour : dict
    delta_e_map : (rows, cols) float32 or None
        :func:`measure_colour`'s.
    seen : dict or None
        For the part's colour (:func:`workbench.validate.part_colour.fused_colour`): ``facing``
        (rows, cols) float16, the cosine of the angle between the surface's normal and the
        direction to the camera at every pixel the photo scores (1: seen square on; NaN
        elsewhere), and ``weight``, the compared pixels each sample of ``delta_e_map`` stands for.
    """

    scored = np.isin(state, (print_warp.COLOUR_ONLY, print_warp.UNRESOLVED, print_warp.NORMAL, print_warp.FULL))
    regions = {f"view {v['name']}": grid.owner == k for k, v in enumerate(design.info["views"])}
    for f in design.info.get("films") or []:
        box = np.zeros(scored.shape, bool)
        i0, j0 = (np.asarray(f["atlas_px"][:2]) / grid.factor).round().astype(int)
        box[i0 : i0 + round(f["height_px"] / grid.factor), j0 : j0 + round(f["width_px"] / grid.factor)] = True
        regions[f"film {f['name']}"] = box
    normal = grid.normal
    if normal is None:  # (a grid made without the part's normals: each triangle's own, the best there is)
        normal = face_normals(np.asarray(design.V, dtype=np.float64), np.asarray(design.F))[np.maximum(grid.face, 0)]
    colour, de_map = measure_colour(
        photo,
        cam,
        design.fixture.get("colour_chart"),
        warped,
        scored,
        grid.reference if reference is None else reference,
        regions=regions,
        output_profile=output_profile,
        part_depth=depth,
        photo_px_per_grid_px=footprint,
        normal=normal,
        opts=opts,
    )
    if de_map is None:
        return colour, None, None
    # each scored pixel's viewing angle, for the part to tell which photo sees it most squarely
    on = scored & (grid.face >= 0)
    towards = np.asarray(cam.center, np.float64) - grid.X[on]
    facing = np.full(de_map.shape, np.nan, np.float16)  # (to a thousandth: enough to tell the squarer view)
    facing[on] = (normal[on] * towards).sum(axis=1) / np.linalg.norm(towards, axis=1)
    # (each sample stands for this many compared pixels: the subsample's even share of them)
    weight = colour["compared_pixels"] / max(colour["delta_e00"]["pixels"], 1)
    return colour, de_map, {"facing": facing, "weight": float(weight)}

"""Where the film really landed: the dense field as a landing q = p + d(p), per photo and fused.

The dense misregistration m at the print grid's pixel y says that the film point printed
at p = y - m shows where the design puts y: it landed at q = y, so d(p) = m (print mm).
Per photo the field is averaged over blocks of ``SPACING_MM`` (the flow's pixels within a
window are not independent anyway), and the photos of one part are fused per block by
inverse variance. validate writes the arrays to ``landing.npz`` beside validation.json
(referenced with its sha256) and the figures to validation.json's ``landing``; ``workbench
calibrate forming`` reads both.
"""

from __future__ import annotations

import hashlib
import io
import zipfile

import cv2
import numpy as np
from scipy import ndimage

from workbench.validate.dense import REGISTRATION_BLUR_PX, DenseResult, masked_normalise
from workbench.validate.print_warp import EDGE, EDGE_PX, MEASURED, PrintGrid

SPACING_MM = 1.0  # block of the landing grid, print mm
MIN_BLOCK_SHARE = 0.25  # a block is measured when this share of its pixels measures the full vector
# a pixel's flow is kept when its uncertainty (print mm) is at most MAX_SIGMA_MM, or where the
# photo samples the print coarser, at most SIGMA_OF_MEDIAN times the photo's median over the
# pixels that measure the full vector: the landing is a calibration, it wants the photo's
# well-textured pixels only, and the profile weighs each point by 1 / sigma² anyway. (An
# absolute 0.05 mm alone kept half of the face mask's photos at 0.3 mm a photo pixel, median
# sigma 0.047 mm, and left its films' rims, where the forming law moves most, unmeasured.)
MAX_SIGMA_MM = 0.05
SIGMA_OF_MEDIAN = 2.0
# The flow of the dense field sees the print in place of the photo where the photo is not
# scored (no motion there), and its patches and smoothing drag the motion towards none over
# about 15 analysis-grid pixels from what is scored (the law's truth against the landing: biased
# by 0.03 to 0.2 mm median there, at 100 and 300 dpi alike). The landing refines that flow by
# Lucas-Kanade whose windows hold the scored pixels only, and keeps a pixel whose window is at
# least this much scored (its uncertainty grows as the window shrinks).
LK_WINDOW_PX = 5.0  # Gaussian sigma of the refinement's window, grid px
LK_NORM_PX = 6.0  # window of the local exposure normalisation, grid px (the flow's)
LK_ITERATIONS = 5
LK_DAMPING = 0.2  # Levenberg-Marquardt damping, relative to the window's gradient energy
MAX_REFINE_PX = 1.5  # farther from the flow than this, the refinement is not trusted
MIN_WINDOW_SHARE = 0.5
# The band of EDGE_PX grid pixels that validate leaves unscored along the rim of what a photo
# sees (its flow and exposure fit have neighbours on one side only) is 3 mm wide on a print
# analysed at 0.5 mm a pixel: the films' rims, where forming moves the film most. On the
# calibration film (a locally unique pattern: nothing there repeats to lock onto) the
# landing measures it by the same masked Lucas-Kanade, started from the flow of the nearest
# scored pixel (the dense flow there is dragged towards none). Not on a decorated print:
# on the default job's checker its rim blocks were 0.14 mm off (median) after every check
# below, against 0.06 mm on the face mask's calibration film. A rim pixel is kept when its
# window's weakest gradient energy is at least RIM_TEXTURE_QUANTILE of the scored pixels'
# it keeps (texture in both directions, as they have), its uncertainty scaled from theirs by
# that energy (Lucas-Kanade's error goes as 1 / sqrt of it), and when it agrees with the
# nearest kept scored pixel within RIM_Z of both uncertainties plus RIM_SLOPE per mm between
# them: a forming field is smooth over millimetres, while a window that locks one period off
# on a periodic print (a checker) is a period off.
RIM_TEXTURE_QUANTILE = 10.0  # percentile
RIM_Z = 3.0
RIM_SLOPE = 0.05  # mm per mm: 5 % strain between the rim and its neighbour, beyond any forming law's change
RIM_REACH_PX = 2 * EDGE_PX  # a rim pixel farther than this from a kept scored one (grid px) has none to agree with


def refine_flow(
    reference: np.ndarray, photo: np.ndarray, scored: np.ndarray, flow_px: np.ndarray, blur_px: float, scale: float
):
    """The dense field's flow refined where the photo is scored, by Lucas-Kanade on scored pixels alone.

    Both images are smoothed as the flow smoothed them (to the photo's resolution where it is
    coarser than the grid), and the print also by the photo's own blur, so that the print
    predicts the photo; the steps are damped where a window's texture leaves a direction
    undetermined (Levenberg-Marquardt), and a pixel the refinement moves more than
    ``MAX_REFINE_PX`` from the flow is not trusted (neither says where it is).

    Parameters
    ----------
    reference, photo : (H, W, 3) uint8
        The print on the analysis grid and the photo warped onto it.
    scored : (H, W) bool
        Where the photo is measured.
    flow_px : (H, W, 2) float
        Misregistration m, grid px: the photo shows at y what the print has at y - m; the
        refinement starts there.
    blur_px : float
        The photo's blur on the grid relative to the print (Gaussian sigma).
    scale : float
        Photo pixels per grid pixel.

    Returns
    -------
    m : (H, W, 2) float32
        The refined misregistration, grid px (NaN where not trusted).
    share : (H, W) float32
        The share of each pixel's window that is scored.
    energy : (H, W) float32
        The smaller eigenvalue of the window's gradient tensor over its share (the normalised
        images' squared gradient per pixel): how well the window's texture fixes the weaker
        direction.
    """
    reg = max(REGISTRATION_BLUR_PX, REGISTRATION_BLUR_PX / max(scale, 1e-3))
    P = cv2.cvtColor(reference, cv2.COLOR_RGB2GRAY).astype(np.float32)
    F = cv2.cvtColor(photo, cv2.COLOR_RGB2GRAY).astype(np.float32)
    P = cv2.GaussianBlur(P, (0, 0), float(np.hypot(reg, max(blur_px, 0.0))))
    F = cv2.GaussianBlur(F, (0, 0), reg)
    w = scored.astype(np.float32)
    Fn = masked_normalise(F, w, LK_NORM_PX)
    H, W = w.shape
    jj, ii = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    g0 = -np.nan_to_num(flow_px.astype(np.float32))  # print(y + g) ≈ photo(y)
    g = g0.copy()

    def win(a):
        return cv2.GaussianBlur(a, (0, 0), LK_WINDOW_PX)

    share = win(w)
    for _ in range(LK_ITERATIONS):
        Pw = cv2.remap(P, jj + g[..., 0], ii + g[..., 1], cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
        Pn = masked_normalise(Pw, w, LK_NORM_PX)
        gx = cv2.Scharr(Pn, cv2.CV_32F, 1, 0) / 32.0
        gy = cv2.Scharr(Pn, cv2.CV_32F, 0, 1) / 32.0
        r = (Pn - Fn) * w
        a11, a12, a22 = win(w * gx * gx), win(w * gx * gy), win(w * gy * gy)
        # the tensor's smaller eigenvalue: (a11 + a22) / 2 - sqrt(((a11 - a22) / 2)² + a12²)
        energy = 0.5 * (a11 + a22) - np.sqrt(0.25 * (a11 - a22) ** 2 + a12 * a12)
        b1, b2 = win(gx * r), win(gy * r)
        # damped: a direction the window's texture does not determine barely moves
        mu = LK_DAMPING * (a11 + a22) + 1e-6
        a11, a22 = a11 + mu, a22 + mu
        det = a11 * a22 - a12 * a12
        dx = -(a22 * b1 - a12 * b2) / det
        dy = -(a11 * b2 - a12 * b1) / det
        n = np.maximum(1.0, np.hypot(dx, dy))  # at most a pixel a step (the linearisation's reach)
        g[..., 0] += dx / n
        g[..., 1] += dy / n
    m = -g
    m[np.hypot(*(g - g0).transpose(2, 0, 1)) > MAX_REFINE_PX] = np.nan
    return m, share, energy / np.maximum(share, 1e-6)


def film_of_face(info: dict, n_faces: int) -> np.ndarray | None:
    """With several films, the film (0-based) of each face of decorated.obj (design.json's ``films``'
    ``atlas_faces``); None for a design of one film."""
    films = info.get("films")
    if not films:
        return None
    out = np.full(n_faces, -1, np.int32)
    for k, f in enumerate(films):
        lo, hi = f["atlas_faces"]
        out[lo:hi] = k
    return out


def rim_measured(flow, sigma, ok, rim, energy, px_per_mm: float, cap: float):
    """The rim pixels whose refined flow the landing keeps, beside the scored ones (RIM_* above).

    Parameters
    ----------
    flow : (H, W, 2) float
        Refined misregistration, grid px.
    sigma : (H, W) float
        Uncertainty per component, print mm (NaN where unknown).
    ok : (H, W) bool
        The scored pixels kept.
    rim : (H, W) bool
        The rim pixels whose refinement converged with enough of its window.
    energy : (H, W) float
        :func:`refine_flow`'s weakest gradient energy per window pixel.
    px_per_mm : float
        Grid pixels per print mm.
    cap : float
        The largest uncertainty kept, print mm.

    Returns
    -------
    sigma : (H, W) float
        ``sigma`` with the kept rim pixels' uncertainty.
    ok : (H, W) bool
        ``ok`` with the kept rim pixels.
    """
    e_ok = energy[ok]
    floor = np.percentile(e_ok, RIM_TEXTURE_QUANTILE)
    cand = rim & ~ok & (energy >= floor)
    if not cand.any():
        return sigma, ok
    with np.errstate(invalid="ignore", divide="ignore"):
        # Lucas-Kanade's error: noise / sqrt(gradient energy), scaled from the scored pixels' own
        s_rim = float(np.median(sigma[ok])) * np.sqrt(float(np.median(e_ok)) / energy)
    dist, (ni, nj) = ndimage.distance_transform_edt(~ok, return_indices=True)
    dev = np.hypot(*(flow - flow[ni, nj]).transpose(2, 0, 1)) / px_per_mm
    allowed = RIM_Z * np.hypot(s_rim, sigma[ni, nj]) + RIM_SLOPE * dist / px_per_mm
    keep = cand & (dist <= RIM_REACH_PX) & (dev <= allowed) & (s_rim <= cap)
    return np.where(keep, s_rim, sigma), ok | keep


def photo_landing(
    dr: DenseResult, grid: PrintGrid, face_film: np.ndarray | None = None, scale: float = 1.0, rim: bool = False
) -> dict:
    """One photo's landing on the blocks of the print grid.

    Parameters
    ----------
    dr : DenseResult
        The photo's dense field (:func:`workbench.validate.dense.analyse`).
    grid : PrintGrid
        The print's analysis grid.
    face_film : (#F,) int, optional
        With several films, the film of each face (:func:`film_of_face`): each block then says
        which film it is on (``film``), since each film has its own forming field.
    scale : float
        Photo pixels per grid pixel (:func:`workbench.validate.print_warp.warp_to_print`).
    rim : bool
        Measure the unscored band along the rim of what the photo sees too: for a print that
        is locally unique (the calibration film), see RIM_* above.

    Returns
    -------
    dict
        ``block`` (n,) int: block index (row-major over blocks of ``SPACING_MM``); ``q_mm``
        (n, 2): where the block's film landed, print mm (x right, y down); ``d_mm`` (n, 2): its
        displacement, print mm; ``sigma_mm`` (n,): standard uncertainty of each component,
        print mm; ``blocks`` (2,): blocks per row and per column; with ``face_film``, ``film`` (n,)
        int: the film under the block's measured pixels.
    """
    b = max(1, int(round(SPACING_MM * grid.px_per_mm)))
    rows, cols = dr.texture.shape
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma = dr.sigma_mm / grid.surface_per_print  # surface mm to print mm
    flow = dr.flow_px
    band = energy = share = None
    if getattr(dr, "state", None) is not None and getattr(dr, "warped", None) is not None:
        scored = np.isin(dr.state, MEASURED)
        band = (dr.state == EDGE) if rim else np.zeros_like(scored)
        start = dr.flow_px
        if band.any() and scored.any():
            # (a rim pixel starts from its nearest scored pixel's flow)
            _, (ni, nj) = ndimage.distance_transform_edt(~scored, return_indices=True)
            start = np.where(band[..., None], dr.flow_px[ni, nj], dr.flow_px)
        flow, share, energy = refine_flow(
            grid.reference, dr.warped, scored | band, start, float(dr.blur_px or 0.0), scale
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            # a window cut short by what is not scored holds fewer pixels: less certain
            sigma = sigma / np.sqrt(np.clip(share, MIN_WINDOW_SHARE, 1.0))
        sigma = np.where(share >= MIN_WINDOW_SHARE, sigma, np.nan)
    finite = np.isfinite(flow[..., 0]) & np.isfinite(flow[..., 1])
    full = (dr.texture == 2) & np.isfinite(sigma) & finite
    cap = max(MAX_SIGMA_MM, SIGMA_OF_MEDIAN * float(np.median(sigma[full]))) if full.any() else MAX_SIGMA_MM
    ok = full & (sigma <= cap)
    if band is not None and band.any() and ok.any():
        usable = band & finite & (share >= MIN_WINDOW_SHARE)
        sigma, ok = rim_measured(flow, sigma, ok, usable, energy, grid.px_per_mm, cap)
    br, bc = rows // b, cols // b
    # pixels per block (row-major over blocks; within one, row-major over its b x b pixels)
    n = ok[: br * b, : bc * b].reshape(br, b, bc, b).sum(axis=(1, 3), dtype=np.int64).ravel().astype(np.float64)
    keep = n >= MIN_BLOCK_SHARE * b * b
    idx = np.nonzero(keep)[0]
    # the kept blocks' pixels only (most of a photo's blocks, but not the whole grid's copies):
    # each block's sums over its pixels in the same order as over the whole grid's blocks
    bi, bj = np.divmod(idx, bc)
    k = np.arange(b * b)
    ii = bi[:, None] * b + k[None, :] // b
    jj = bj[:, None] * b + k[None, :] % b
    w = ok[ii, jj].astype(np.float64)
    y = np.stack([jj + 0.5, ii + 0.5], axis=-1) / grid.px_per_mm
    m = np.nan_to_num(flow[ii, jj].astype(np.float64)) / grid.px_per_mm  # (a pixel not kept weighs nothing)
    with np.errstate(invalid="ignore", divide="ignore"):
        q = (y * w[..., None]).sum(axis=1) / n[idx, None]
        d = (m * w[..., None]).sum(axis=1) / n[idx, None]
    s = np.where(ok[ii, jj], sigma[ii, jj], np.nan)
    out = {
        "block": idx.astype(np.int32),
        "q_mm": q,
        "d_mm": d,
        # (the block's pixels share their flow windows: the median pixel's uncertainty, not divided by n)
        "sigma_mm": np.nanmedian(s, axis=1) if len(idx) else np.zeros(0),
        "blocks": np.array([bc, br], np.int32),
    }
    if face_film is not None:
        # films lie ATLAS_GAP_MM (5 mm) apart on the print: a 1 mm block's measured pixels are on one
        face = grid.face[ii, jj]
        f = np.where(ok[ii, jj] & (face >= 0), face_film[np.maximum(face, 0)], -1)
        out["film"] = (f.max(axis=1) if len(idx) else np.zeros(0, np.int64)).astype(np.int32)
    return out


def fuse(landings: list[dict]) -> dict:
    """The photos' landings of one part fused per block: inverse-variance means of q and d."""
    ls = [x for x in landings if x is not None and len(x["block"])]
    if not ls:
        return {
            "block": np.zeros(0, np.int32),
            "q_mm": np.zeros((0, 2)),
            "d_mm": np.zeros((0, 2)),
            "sigma_mm": np.zeros(0),
        }
    block = np.concatenate([x["block"] for x in ls])
    film = np.concatenate([x["film"] for x in ls]) if all("film" in x for x in ls) else None
    w = np.concatenate([1.0 / np.maximum(x["sigma_mm"], 1e-6) ** 2 for x in ls])
    q = np.concatenate([x["q_mm"] for x in ls])
    d = np.concatenate([x["d_mm"] for x in ls])
    u, inv = np.unique(block, return_inverse=True)
    W = np.bincount(inv, w, len(u))
    out_q = np.stack([np.bincount(inv, w * q[:, k], len(u)) / W for k in range(2)], axis=1)
    out_d = np.stack([np.bincount(inv, w * d[:, k], len(u)) / W for k in range(2)], axis=1)
    out = {"block": u.astype(np.int32), "q_mm": out_q, "d_mm": out_d, "sigma_mm": 1.0 / np.sqrt(W)}
    if film is not None:
        out["film"] = np.zeros(len(u), np.int32)
        out["film"][inv] = film  # (a block is on one film in every photo)
    return out


def summary(landing: dict) -> dict:
    """validation.json's figures of one landing."""
    d = np.linalg.norm(landing["d_mm"], axis=1) if len(landing["block"]) else np.zeros(0)
    s = landing["sigma_mm"]
    return {
        "points": int(len(d)),
        "d_median_mm": float(np.median(d)) if len(d) else None,
        "d_p95_mm": float(np.percentile(d, 95)) if len(d) else None,
        "sigma_median_mm": float(np.median(s)) if len(s) else None,
    }


def npz_bytes(arrays: dict) -> bytes:
    """``np.savez_compressed``'s format with fixed member dates: the same arrays give the same bytes."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, a in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asarray(a), allow_pickle=False)
            z.writestr(zipfile.ZipInfo(f"{name}.npy", (1980, 1, 1, 0, 0, 0)), member.getvalue(), zipfile.ZIP_DEFLATED)
    return buf.getvalue()


def add_to_report(report: dict, entries: list[dict], out) -> dict:
    """Take each photo's landing arrays out of its entry, fuse them, and return the side file.

    Each entry keeps its landing's figures; ``report["landing"]`` gets the fused figures
    and the side file's name and sha256. Returns ``{path: bytes}`` of ``landing.npz``.
    """
    arrays: dict = {}
    landings = []
    for k, e in enumerate(entries):
        got = e.pop("landing", None)
        landings.append(got)
        if got is None:
            continue
        e["landing"] = {"index": k, **summary(got)}
        for key in ("block", "q_mm", "d_mm", "sigma_mm", "film"):
            if key in got:
                arrays[f"photo{k}_{key}"] = got[key]
        arrays["blocks"] = got["blocks"]
    fused = fuse(landings)
    for key in ("block", "q_mm", "d_mm", "sigma_mm", "film"):
        if key in fused:
            arrays[f"fused_{key}"] = fused[key]
    data = npz_bytes(arrays)
    report["landing"] = {
        "file": "landing.npz",
        "sha256": hashlib.sha256(data).hexdigest(),
        "spacing_mm": SPACING_MM,
        "note": (
            "where the film landed: per block of the print, the film point p = q - d printed there landed where the "
            "design puts q (print mm of this design, x right, y down); d and its standard uncertainty per component "
            "(sigma), per photo (photoK_*) and fused over the photos (fused_*); with several films, the film (0-based, "
            "design.json's films) of each block (film): what workbench calibrate forming reads"
        ),
        **summary(fused),
    }
    return {out / "landing.npz": data}

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

import numpy as np

from workbench.validate.dense import DenseResult, PrintGrid

SPACING_MM = 1.0  # block of the landing grid, print mm
MIN_BLOCK_SHARE = 0.25  # a block is measured when this share of its pixels measures the full vector
# a pixel's flow is kept when its uncertainty (print mm) is at most this: the landing is a
# calibration, it wants the well-textured pixels only
MAX_SIGMA_MM = 0.05


def photo_landing(dr: DenseResult, grid: PrintGrid) -> dict:
    """One photo's landing on the blocks of the print grid.

    Parameters
    ----------
    dr : DenseResult
        The photo's dense field (:func:`workbench.validate.dense.analyse`).
    grid : PrintGrid
        The print's analysis grid.

    Returns
    -------
    dict
        ``block`` (n,) int: block index (row-major over blocks of ``SPACING_MM``); ``q_mm``
        (n, 2): where the block's film landed, print mm (x right, y down); ``d_mm`` (n, 2): its
        displacement, print mm; ``sigma_mm`` (n,): standard uncertainty of each component,
        print mm; ``blocks`` (2,): blocks per row and per column.
    """
    b = max(1, int(round(SPACING_MM * grid.px_per_mm)))
    rows, cols = dr.texture.shape
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma = dr.sigma_mm / grid.surface_per_print  # surface mm to print mm
    finite = np.isfinite(dr.flow_px[..., 0]) & np.isfinite(dr.flow_px[..., 1])
    ok = (dr.texture == 2) & np.isfinite(sigma) & (sigma <= MAX_SIGMA_MM) & finite
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
    m = dr.flow_px[ii, jj].astype(np.float64) / grid.px_per_mm
    with np.errstate(invalid="ignore", divide="ignore"):
        q = (y * w[..., None]).sum(axis=1) / n[idx, None]
        d = (m * w[..., None]).sum(axis=1) / n[idx, None]
    s = np.where(ok[ii, jj], sigma[ii, jj], np.nan)
    return {
        "block": idx.astype(np.int32),
        "q_mm": q,
        "d_mm": d,
        # (the block's pixels share their flow windows: the median pixel's uncertainty, not divided by n)
        "sigma_mm": np.nanmedian(s, axis=1) if len(idx) else np.zeros(0),
        "blocks": np.array([bc, br], np.int32),
    }


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
    w = np.concatenate([1.0 / np.maximum(x["sigma_mm"], 1e-6) ** 2 for x in ls])
    q = np.concatenate([x["q_mm"] for x in ls])
    d = np.concatenate([x["d_mm"] for x in ls])
    u, inv = np.unique(block, return_inverse=True)
    W = np.bincount(inv, w, len(u))
    out_q = np.stack([np.bincount(inv, w * q[:, k], len(u)) / W for k in range(2)], axis=1)
    out_d = np.stack([np.bincount(inv, w * d[:, k], len(u)) / W for k in range(2)], axis=1)
    return {"block": u.astype(np.int32), "q_mm": out_q, "d_mm": out_d, "sigma_mm": 1.0 / np.sqrt(W)}


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
        for key in ("block", "q_mm", "d_mm", "sigma_mm"):
            arrays[f"photo{k}_{key}"] = got[key]
        arrays["blocks"] = got["blocks"]
    fused = fuse(landings)
    for key in ("block", "q_mm", "d_mm", "sigma_mm"):
        arrays[f"fused_{key}"] = fused[key]
    data = npz_bytes(arrays)
    report["landing"] = {
        "file": "landing.npz",
        "sha256": hashlib.sha256(data).hexdigest(),
        "spacing_mm": SPACING_MM,
        "note": (
            "where the film landed: per block of the print, the film point p = q - d printed there landed where the "
            "design puts q (print mm of this design, x right, y down); d and its standard uncertainty per component "
            "(sigma), per photo (photoK_*) and fused over the photos (fused_*): what workbench calibrate forming reads"
        ),
        **summary(fused),
    }
    return {out / "landing.npz": data}

"""Forming calibration: a smooth landing field d(p) fitted to the validations of formed sheets.

Each sheet (one validation folder: one or more photos of one formed film) gives, per block
of the print, where its film landed (``landing.npz`` of ``workbench validate``). The
profile is a penalised cubic B-spline (P-spline: Eilers and Marx 1996) fitted to all sheets'
points, weighted by their uncertainty, its smoothing chosen by spatially blocked
cross-validation; each sheet is fitted alone with the same smoothing, and the spread of the
sheets' fields about the mean is the repeatability (the random part of forming, which a
profile cannot compensate and which therefore stays out of it: the mean over sheets is
what is fitted).

Fields are on the uncompensated design's print (mm, x right, y down). A validation of a
design that was itself compensated by a profile d₁ measures the residual r on that
design's print; the film's landing on the uncompensated print is then (id + d₁)(q - o)
(o: where the uncompensated print's corner sits in the compensated one): the fields compose.

Numerics only; ``workbench/commands/calibrate.py`` reads and writes the files.
"""

from __future__ import annotations

import hashlib
import io
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import BSpline
from scipy.spatial import cKDTree

from workbench import forming as fm
from workbench.errors import WorkbenchError
from workbench.jsonfile import read_json, resolve_recorded

KNOT_MM = 4.0  # B-spline knot spacing: finer than any forming law's features (tens of mm) ...
KNOTS_ACROSS = 30  # ... but at most this many knot intervals across the print (a 0.5 m face mask: 16 mm)
MARGIN_MM = 10.0  # the field's domain reaches this far beyond the print (compensation looks there)
MIN_POINTS = 50  # measured blocks a film needs for a fit
MIN_SIGMA_MM = 0.005  # a block's uncertainty is taken as at least this (the flow's own floor)
OUTLIER_Z = 5.0  # a block this many of its uncertainties off the fit is dropped (a defect, a bad match)
LAMBDAS = 10.0 ** np.arange(-3.0, 5.01, 0.5)  # smoothing candidates (relative to the data's weight)
CV_BLOCK_MM = 12.0  # cross-validation folds are squares of this size: neighbours are correlated
CV_FOLDS = 5
EXTRAPOLATION_MM = 3.0  # film farther than this from a measured block is extrapolated
EXTRAPOLATION_WARN_SHARE = 0.05  # a warning when more of the film than this is extrapolated


@dataclass
class Sheet:
    """One formed sheet's landing on the uncompensated print.

    Attributes
    ----------
    name : str
        The validation folder.
    p : (n, 2) float
        Film points (uncompensated print mm).
    d : (n, 2) float
        Where each landed, relative to it: nominal position p + d, mm.
    sigma : (n,) float
        Standard uncertainty per component, mm.
    design : dict
        design.json of the design photographed.
    design_dir : Path
    validation : dict
        ``file`` and ``sha256`` of its validation.json.
    """

    name: str
    p: np.ndarray
    d: np.ndarray
    sigma: np.ndarray
    design: dict
    design_dir: Path
    validation: dict


def read_sheet(folder: Path) -> Sheet:
    """One sheet's landing on the uncompensated print (composed with the design's profile).

    ``folder`` is a validation folder, or a folder of them (one per camera: photos of one
    sheet from several views, each validated with its own camera profile).
    """
    if folder.is_dir() and not (folder / "validation.json").exists():
        subs = sorted(f for f in folder.iterdir() if (f / "validation.json").is_file())
        if subs:
            parts = [read_sheet(f) for f in subs]
            check_same_design(parts)
            return Sheet(
                str(folder),
                np.concatenate([s.p for s in parts]),
                np.concatenate([s.d for s in parts]),
                np.concatenate([s.sigma for s in parts]),
                parts[0].design,
                parts[0].design_dir,
                {"file": str(folder), "sha256": None, "parts": [s.validation for s in parts]},
            )
    vj = folder / "validation.json"
    if folder.is_file():
        raise WorkbenchError(f"{folder}: a validation folder (workbench validate --out) expected, not a file")
    rep = read_json(vj, "validation.json of workbench validate")
    lan = rep.get("landing")
    if not isinstance(lan, dict) or not isinstance(lan.get("file"), str):
        raise WorkbenchError(f"{vj}: landing: missing (validate it again with this version of workbench validate)")
    npz = resolve_recorded(lan["file"], vj)
    if not npz.is_file():
        raise WorkbenchError(f"{npz}: missing; validation.json records it as its landing")
    data = npz.read_bytes()
    if hashlib.sha256(data).hexdigest() != lan.get("sha256"):
        raise WorkbenchError(f"{npz}: not the landing validation.json records (its sha256 differs)")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            q, d, s = (np.asarray(z[f"fused_{k}"], np.float64) for k in ("q_mm", "d_mm", "sigma_mm"))
    except (KeyError, ValueError, OSError, zipfile.BadZipFile) as exc:
        raise WorkbenchError(f"{npz}: not a landing file ({exc})") from None
    if q.ndim != 2 or q.shape[1:] != (2,) or d.shape != q.shape or s.shape != q.shape[:1]:
        raise WorkbenchError(f"{npz}: fused_q_mm, fused_d_mm (n, 2) and fused_sigma_mm (n,) expected")
    ok = np.isfinite(q).all(1) & np.isfinite(d).all(1) & np.isfinite(s)
    q, d, s = q[ok], d[ok], s[ok]
    design = rep.get("design") or {}
    if not isinstance(design.get("dir"), str):
        raise WorkbenchError(f"{vj}: design.dir: missing")
    ddir = resolve_recorded(design["dir"], vj)
    dj = ddir / "design.json"
    if not dj.is_file():
        raise WorkbenchError(f"{dj}: missing; {vj} was made from that design")
    if hashlib.sha256(dj.read_bytes()).hexdigest() != design.get("design_json_sha256"):
        raise WorkbenchError(f"{dj}: not the design {vj} was made from (design.json changed since)")
    from workbench.design_dir import Design

    des = Design(ddir)
    o = des.frame_offset_mm()
    comp = des.compensation()
    # the film point printed at p = q - d landed where this design puts q; on the uncompensated
    # print, that is x = q - o and it landed at x + d₁(x)
    p = q - d - o
    x = q - o
    landed = x if comp is None else x + comp(x)
    return Sheet(
        str(folder),
        p,
        landed - p,
        s,
        des.info,
        ddir,
        {"file": str(vj), "sha256": hashlib.sha256(vj.read_bytes()).hexdigest()},
    )


def check_same_design(sheets: list[Sheet]) -> None:
    """All sheets are validations of one design: the first's."""
    ref = sheets[0]
    for s in sheets[1:]:
        a, b = fm.design_identity(ref.design), fm.design_identity(s.design)
        if a != b or ref.design.get("forming") != s.design.get("forming"):
            what = next((k for k in a if a[k] != b[k]), "forming compensation")
            raise WorkbenchError(
                f"{s.validation['file']}: a validation of another design than {ref.validation['file']} "
                f"({what} differs): every sheet must be of one design"
            )


@dataclass
class Spline2D:
    """The P-spline's basis over a rectangle."""

    tx: np.ndarray
    ty: np.ndarray

    @classmethod
    def over(cls, lo, hi, knot_mm: float = KNOT_MM) -> Spline2D:
        def knots(a, b):
            n = max(1, int(np.ceil((b - a) / knot_mm)))
            inner = np.linspace(a, b, n + 1)
            return np.concatenate([[a] * 3, inner, [b] * 3])

        return cls(knots(lo[0], hi[0]), knots(lo[1], hi[1]))

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.tx) - 4, len(self.ty) - 4

    def design(self, p: np.ndarray) -> sp.csr_matrix:
        """Rows of the tensor-product basis at p (clamped to the domain); (n, nx * ny), column i * ny + j."""
        x = np.clip(p[:, 0], self.tx[3], self.tx[-4] - 1e-9)
        y = np.clip(p[:, 1], self.ty[3], self.ty[-4] - 1e-9)
        Bx = BSpline.design_matrix(x, self.tx, 3).tocsr()
        By = BSpline.design_matrix(y, self.ty, 3).tocsr()
        nx, ny = self.shape
        # the row-wise Kronecker product: 16 non-zeros a row
        rows = np.repeat(np.arange(len(p)), 16)
        bx = Bx.indices.reshape(-1, 4)
        by = By.indices.reshape(-1, 4)
        cols = (bx[:, :, None] * ny + by[:, None, :]).reshape(-1)
        vals = (Bx.data.reshape(-1, 4)[:, :, None] * By.data.reshape(-1, 4)[:, None, :]).reshape(-1)
        return sp.csr_matrix((vals, (rows, cols)), shape=(len(p), nx * ny))

    def penalty(self) -> sp.csr_matrix:
        """Second differences of the coefficients along x and along y (and a whisper of ridge)."""
        nx, ny = self.shape

        def d2(n):
            return sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(max(n - 2, 0), n))

        Dx = sp.kron(d2(nx), sp.identity(ny))
        Dy = sp.kron(sp.identity(nx), d2(ny))
        return (Dx.T @ Dx + Dy.T @ Dy + 1e-8 * sp.identity(nx * ny)).tocsr()

    def field(self, coef: np.ndarray) -> fm.SplineField:
        nx, ny = self.shape
        return fm.SplineField(self.tx.copy(), self.ty.copy(), coef.reshape(nx, ny, 2))


def _solve(B, w, d, P, lam):
    A = (B.T @ sp.diags(w) @ B + lam * P).tocsc()
    rhs = B.T @ (w[:, None] * d)
    from scipy.sparse.linalg import splu

    lu = splu(A, permc_spec="MMD_AT_PLUS_A")
    return lu.solve(np.ascontiguousarray(rhs))


def fit_field(basis: Spline2D, p, d, sigma, lam: float | None = None):
    """Penalised least squares of d(p) on the basis, outliers dropped; smoothing by blocked CV when ``lam`` is None.

    Returns
    -------
    coef : (nx * ny, 2) float
    lam : float
        The smoothing used (absolute: times the penalty).
    info : dict
        ``cv_rms_mm``, ``fit_rms_mm``, ``points``, ``outliers``, ``keep`` (n,) bool.
    """
    s = np.maximum(sigma, MIN_SIGMA_MM)
    w = 1.0 / s**2
    B = basis.design(p)
    P = basis.penalty()
    scale = float(w.sum()) / max(P.shape[0], 1)  # λ relative to the data's total weight per coefficient
    keep = np.ones(len(p), bool)

    def drop_outliers(keep, lam_abs):
        for _ in range(3):
            c = _solve(B[keep], w[keep], d[keep], P, lam_abs)
            z = np.linalg.norm(B @ c - d, axis=1) / s
            # (beyond OUTLIER_Z standard uncertainties, or far beyond the typical residual where the
            # uncertainties are optimistic)
            new = z <= max(OUTLIER_Z * np.sqrt(2.0), 4.0 * float(np.median(z[keep])))
            if new.sum() < MIN_POINTS or (new == keep).all():
                return keep, c
            keep = new
        return keep, c

    def cross_validate(keep):
        Bk, wk, dk, pk = B[keep], w[keep], d[keep], p[keep]
        cell = np.floor(pk / CV_BLOCK_MM).astype(np.int64)
        fold = (cell[:, 0] * 7 + cell[:, 1] * 3) % CV_FOLDS
        errs, rms = [], []
        for rl in LAMBDAS:
            e, e2, n = 0.0, 0.0, 0
            for f in range(CV_FOLDS):
                tr, te = fold != f, fold == f
                if not te.any() or tr.sum() < 16:
                    continue
                c = _solve(Bk[tr], wk[tr], dk[tr], P, rl * scale)
                r = Bk[te] @ c - dk[te]
                e += float((wk[te][:, None] * r * r).sum())
                e2, n = e2 + float((r * r).sum()), n + int(te.sum())
            errs.append(e)
            rms.append(np.sqrt(e2 / max(n, 1)))
        best = int(np.argmin(errs))
        return float(LAMBDAS[best] * scale), float(rms[best])

    cv = None
    if lam is None:
        lam, cv = cross_validate(keep)
        keep, _ = drop_outliers(keep, lam)
        lam, cv = cross_validate(keep)
    keep, c = drop_outliers(keep, lam)
    r = B[keep] @ c - d[keep]
    return (
        c,
        lam,
        {
            "cv_rms_mm": cv,
            "fit_rms_mm": float(np.sqrt((r * r).sum(axis=1).mean())) if keep.any() else None,
            "points": int(keep.sum()),
            "outliers": int((~keep).sum()),
            "keep": keep,
        },
    )


def film_mask_mm(design_dir: Path, info: dict, spacing_mm: float):
    """Points of a regular grid over the uncompensated print that lie on its film; (n, 2) mm."""
    from workbench.design_dir import Design

    des = Design(design_dir)
    W, H = des.base_size_mm()
    xs = np.arange(0.5 * spacing_mm, W, spacing_mm)
    ys = np.arange(0.5 * spacing_mm, H, spacing_mm)
    g = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    if des.alpha is None:
        return g
    o = des.frame_offset_mm()
    ppm = info["print"]["dpi"] / 25.4
    ij = np.floor((g + o) * ppm).astype(int)
    h, w = des.alpha.shape
    inside = (ij[:, 0] >= 0) & (ij[:, 0] < w) & (ij[:, 1] >= 0) & (ij[:, 1] < h)
    on = np.zeros(len(g), bool)
    on[inside] = des.alpha[ij[inside, 1], ij[inside, 0]] > 0
    return g[on]


def calibrate_forming(sheets: list[Sheet]) -> dict:
    """The forming profile's numbers from the sheets (one film: the print).

    Returns
    -------
    dict
        ``field`` (SplineField), ``smoothing``, ``cv_rms_mm``, ``fit_rms_mm``, ``points``,
        ``outliers``, ``repeatability_mm`` (None with one sheet), per-sheet figures,
        ``measured_share`` (and ``measured_share_on_part``), ``extrapolated_share``, ``max_extrapolation_mm``,
        ``extrapolated_at_mm``, ``grid`` (film points) and ``warnings``.
    """
    ref = sheets[0]
    from workbench.design_dir import Design

    W, H = Design(ref.design_dir).base_size_mm()
    for s in sheets:
        if len(s.p) < MIN_POINTS:
            where = ""
            if len(s.p):
                lo, hi = s.p.min(axis=0), s.p.max(axis=0)
                where = f", all within x {lo[0]:.0f} to {hi[0]:.0f} mm, y {lo[1]:.0f} to {hi[1]:.0f} mm of the print"
            raise WorkbenchError(
                f"{s.validation['file']}: {len(s.p)} measured points on the film{where}; a forming profile needs at "
                f"least {MIN_POINTS}: photograph the sheet from its designed views, or print the calibration film "
                "(workbench pdf DESIGN --pattern forming)"
            )
    knot = max(KNOT_MM, max(W, H) / KNOTS_ACROSS)
    basis = Spline2D.over((-MARGIN_MM, -MARGIN_MM), (W + MARGIN_MM, H + MARGIN_MM), knot)
    p = np.concatenate([s.p for s in sheets])
    d = np.concatenate([s.d for s in sheets])
    sig = np.concatenate([s.sigma for s in sheets])
    coef, lam, info = fit_field(basis, p, d, sig)
    field = basis.field(coef)
    per_sheet = []
    fields = []
    for s in sheets:
        c, _, si = fit_field(basis, s.p, s.d, s.sigma, lam)
        fields.append(basis.field(c))
        r = field(s.p) - s.d
        per_sheet.append({"points": int(len(s.p)), "residual_rms_mm": float(np.sqrt((r * r).sum(1).mean()))})
    grid = film_mask_mm(ref.design_dir, ref.design, 1.0)
    dist, _ = cKDTree(p[info["keep"]]).query(grid)
    measured = dist <= 1.0
    landed = fm.land(field, grid) if len(grid) else grid
    on_part = (landed >= 0).all(axis=1) & (landed[:, 0] <= W) & (landed[:, 1] <= H)
    far = dist > EXTRAPOLATION_MM
    rep = None
    if len(sheets) > 1:
        # the sheets' fields where they were all measured: their spread per axis about the mean
        common = grid[measured]
        vals = np.stack([f(common) for f in fields])  # (sheets, n, 2)
        var = vals.var(axis=0, ddof=1)
        rep = float(np.sqrt(var.mean()))
    warnings = []
    far_share = float(far.mean()) if len(grid) else 0.0
    at = grid[np.argmax(dist)].tolist() if len(grid) else None
    if far_share > EXTRAPOLATION_WARN_SHARE:
        warnings.append(
            f"{100 * far_share:.1f} % of the film lies more than {EXTRAPOLATION_MM:g} mm from a measured point "
            f"(up to {dist.max():.1f} mm, at ({at[0]:.0f}, {at[1]:.0f}) mm on the print): the profile extrapolates "
            "there (linearly); photograph the sheets from more views or print the calibration film"
        )
    dmag = np.linalg.norm(field(grid), axis=1) if len(grid) else np.zeros(1)
    return {
        "field": field,
        "sheet_fields": fields,
        "smoothing": lam,
        **{k: v for k, v in info.items() if k != "keep"},
        "repeatability_mm": rep,
        "per_sheet": per_sheet,
        "measured_share": float(measured.mean()) if len(grid) else 0.0,
        # of the film that lands on the part (by the profile, inside the print's rectangle): a film that
        # slides outwards at the rim puts its outer band beyond the part, where no photo can see it
        "measured_share_on_part": float(measured[on_part].mean()) if on_part.any() else 0.0,
        "extrapolated_share": far_share,
        "max_extrapolation_mm": float(dist.max()) if len(grid) else None,
        "extrapolated_at_mm": at,
        "d_median_mm": float(np.median(dmag)),
        "d_p95_mm": float(np.percentile(dmag, 95)),
        "d_max_mm": float(dmag.max()),
        "grid": grid,
        "measured": measured,
        "points_mm": p[info["keep"]],
        "warnings": warnings,
        "size_mm": (W, H),
    }


def profile_picture(result: dict, title: str) -> bytes:
    """The field over the print: |d| in colour, arrows (magnified), measured blocks and extrapolated film."""
    from workbench.figures import _figure, figure_png

    plt = _figure()
    W, H = result["size_mm"]
    xs = np.linspace(0, W, 241)
    ys = np.linspace(0, H, max(2, int(241 * H / W)))
    g = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    d = result["field"](g).reshape(len(ys), len(xs), 2)
    mag = np.linalg.norm(d, axis=2)
    fig, ax = plt.subplots(figsize=(9, 6.5 * H / W + 1.4), dpi=110, layout="constrained")
    im = ax.imshow(mag, extent=(0, W, H, 0), cmap="viridis", origin="upper")
    fig.colorbar(im, ax=ax, label="|d| (mm): how far the film lands from where the design puts it", shrink=0.8)
    step = max(1, len(xs) // 24)
    sub = g.reshape(len(ys), len(xs), 2)[::step, ::step].reshape(-1, 2)
    dv = d[::step, ::step].reshape(-1, 2)
    top = float(np.abs(dv).max()) or 1.0
    k = 0.8 * W / 24 / top
    ax.quiver(sub[:, 0], sub[:, 1], dv[:, 0] * k, dv[:, 1] * k, angles="xy", scale_units="xy", scale=1, color="white")
    # the film nothing measured (grey), and where the profile extrapolates (darker)
    dist, _ = cKDTree(result["points_mm"]).query(g)
    dist = dist.reshape(len(ys), len(xs))
    shade = np.zeros((len(ys), len(xs), 4))
    shade[..., 3] = np.where(dist > EXTRAPOLATION_MM, 0.6, np.where(dist > 1.0, 0.3, 0.0))
    ax.imshow(shade, extent=(0, W, H, 0), origin="upper")
    ax.set_xlim(0, W)
    ax.set_ylim(H, 0)
    ax.set_xlabel("print x (mm)")
    ax.set_ylabel("print y (mm)")
    ax.set_title(
        title + f"\narrows x {k:.1f}; shaded: not measured ({100 * (1 - result['measured_share']):.1f} % of the film), "
        f"dark: more than {EXTRAPOLATION_MM:g} mm from a measurement ({100 * result['extrapolated_share']:.1f} %)",
        fontsize=8,
    )
    return figure_png(fig)

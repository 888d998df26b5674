"""Forming calibration: a smooth landing field d(p) per film, fitted to the validations of formed sheets.

Each sheet (one validation folder: one or more photos of one formed part) gives, per block
of the print, where its film landed (``landing.npz`` of ``workbench validate``; with several
films, which film each block is on). Each film has its own field, on its own uncompensated
print (films are formed one by one).

A sheet's landing is its film's deformation plus where the film was placed on the mould. The
placement is random per sheet (it is what validate's film offset reports, and what the
forming station's registration sets); a forming profile models the deformation. So the fit
is d_s(p) = D(p) + t_s + ω_s J (p - c): one smooth field D (a penalised cubic B-spline,
P-spline: Eilers and Marx 1996, weighted by the points' uncertainty, smoothing by spatially
blocked cross-validation) and, per sheet, its placement's deviation from the sheets' mean
(shift t_s, turn ω_s about the measured film's centre c; they sum to zero). D's own rigid
part over the measured film is the sheets' mean placement m: the systematic placement plus
the mean of the random ones, which no number of sheets tells apart, only bounds (its
standard error is the placements' spread / √n). The profile records D - m (the deformation)
and m with its standard error and whether the sheets show it beyond their own random
placement (an F test at 95 %). By default (``auto``) m is compensated only then: random
scatter does not enter the profile, and a print compensated from sheets placed at random
differs from the one from the same sheets placed alike by less than a standard error on
97.5 % of axes (against 60 % when the mean always goes in: it is the random placements' own
mean). The price is a systematic placement the sheets cannot show beside their spread, up to
about three standard errors, which stays in the parts. ``--placement always`` compensates m
whatever the test (unbiased, with the standard error added to every part), ``never`` leaves
it to the forming station's registration.

The sheets' spread about the profile is the repeatability (what no compensation removes),
reported whole and without the placements.

Fields are on the uncompensated print (mm, x right, y down). A validation of a design that
was itself compensated by a profile d₁ measures the residual r on that design's print; the
film's landing on the uncompensated print is then (id + d₁)(q - o) (o: where the
uncompensated print's corner sits in the compensated one): the fields compose.

Numerics only; ``workbench/commands/calibrate_forming.py`` reads and writes the files.
"""

from __future__ import annotations

import hashlib
import io
import os
import zipfile
from concurrent.futures import ThreadPoolExecutor
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
# ... but at most this many knot intervals across a film (a 0.5 m face mask: 10 mm; cubic B-splines
# with knots 10 mm apart follow a 40 mm wave to 1.5 % of its amplitude, 14 mm apart to 10 %)
KNOTS_ACROSS = 50
MARGIN_MM = 10.0  # the field's domain reaches this far beyond the print (compensation looks there)
MIN_POINTS = 50  # measured blocks a film needs for a fit
MIN_SIGMA_MM = 0.005  # a block's uncertainty is taken as at least this (the flow's own floor)
OUTLIER_Z = 5.0  # a block this many of its uncertainties off the fit is dropped (a defect, a bad match)
LAMBDAS = 10.0 ** np.arange(-3.0, 5.01, 0.5)  # smoothing candidates (relative to the data's weight)
CV_BLOCK_MM = 12.0  # cross-validation folds are squares of this size: neighbours are correlated
CV_FOLDS = 5
EXTRAPOLATION_MM = 3.0  # film farther than this from a measured block is extrapolated
EXTRAPOLATION_WARN_SHARE = 0.05  # a warning when more of the film that lands on the part than this is extrapolated
PLACEMENT_LEVEL = 0.95  # a mean placement is systematic when the sheets show it at this confidence
PLACEMENT_ITERATIONS = 20  # alternations between D and the sheets' placements (converges in a few)
PLACEMENT_TOL_MM = 1e-5


@dataclass
class Sheet:
    """One formed sheet's landing on the uncompensated films' prints.

    Attributes
    ----------
    name : str
        The validation folder.
    p : (n, 2) float
        Film points (mm on their film's uncompensated print).
    d : (n, 2) float
        Where each landed, relative to it: nominal position p + d, mm.
    sigma : (n,) float
        Standard uncertainty per component, mm.
    design : dict
        design.json of the design photographed.
    design_dir : Path
    validation : dict
        ``file`` and ``sha256`` of its validation.json.
    film : (n,) int
        The film of each point (0-based, design.json's ``films``; all 0 for a design of one film).
    """

    name: str
    p: np.ndarray
    d: np.ndarray
    sigma: np.ndarray
    design: dict
    design_dir: Path
    validation: dict
    film: np.ndarray | None = None

    def __post_init__(self):
        if self.film is None:
            self.film = np.zeros(len(self.p), int)

    def of_film(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        on = self.film == k
        return self.p[on], self.d[on], self.sigma[on]


def read_sheet(folder: Path, designs: dict | None = None) -> Sheet:
    """One sheet's landing on the uncompensated films' prints (composed with the design's profile).

    ``folder`` is a validation folder, or a folder of them (one per camera: photos of one
    sheet from several views, each validated with its own camera profile). ``designs``: the
    design folders read so far (path to :class:`~workbench.design_dir.Design`), filled as they
    are read: a design of a 100 k-face mesh takes 2 s to read, and every photo of every
    sheet names the same one.
    """
    if folder.is_dir() and not (folder / "validation.json").exists():
        subs = sorted(f for f in folder.iterdir() if (f / "validation.json").is_file())
        if subs:
            parts = [read_sheet(f, designs) for f in subs]
            check_same_design(parts)
            return Sheet(
                str(folder),
                np.concatenate([s.p for s in parts]),
                np.concatenate([s.d for s in parts]),
                np.concatenate([s.sigma for s in parts]),
                parts[0].design,
                parts[0].design_dir,
                {"file": str(folder), "sha256": None, "parts": [s.validation for s in parts]},
                np.concatenate([s.film for s in parts]),
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
            film = np.asarray(z["fused_film"], np.int64) if "fused_film" in z.files else None
    except (KeyError, ValueError, OSError, zipfile.BadZipFile) as exc:
        raise WorkbenchError(f"{npz}: not a landing file ({exc})") from None
    if q.ndim != 2 or q.shape[1:] != (2,) or d.shape != q.shape or s.shape != q.shape[:1]:
        raise WorkbenchError(f"{npz}: fused_q_mm, fused_d_mm (n, 2) and fused_sigma_mm (n,) expected")
    if film is not None and film.shape != s.shape:
        raise WorkbenchError(f"{npz}: fused_film (n,) expected, as fused_sigma_mm")
    design = rep.get("design") or {}
    if not isinstance(design.get("dir"), str):
        raise WorkbenchError(f"{vj}: design.dir: missing")
    ddir = resolve_recorded(design["dir"], vj)
    dj = ddir / "design.json"
    if not dj.is_file():
        raise WorkbenchError(f"{dj}: missing; {vj} was made from that design")
    if hashlib.sha256(dj.read_bytes()).hexdigest() != design.get("design_json_sha256"):
        raise WorkbenchError(f"{dj}: not the design {vj} was made from (design.json changed since)")

    des = design_of(ddir, designs)
    frames = des.film_frames()
    if film is None:
        if len(frames) > 1:
            raise WorkbenchError(
                f"{npz}: no film per point (fused_film) for a design of {len(frames)} films: validate it again with "
                "this version of workbench validate"
            )
        film = np.zeros(len(q), np.int64)
    ok = np.isfinite(q).all(1) & np.isfinite(d).all(1) & np.isfinite(s) & (film >= 0) & (film < len(frames))
    q, d, s, film = q[ok], d[ok], s[ok], film[ok]
    comps = des.compensations()
    p = np.empty_like(q)
    landed = np.empty_like(q)
    for k, fr in enumerate(frames):
        on = film == k
        # the film point printed at q - d landed where this design puts q; on the film's uncompensated
        # print, that is x = q - o and it landed at x + d₁(x)
        x = q[on] - fr.origin_mm
        p[on] = x - d[on]
        landed[on] = x if comps is None else x + comps[k](x)
    photos = rep.get("photos") or []
    return Sheet(
        str(folder),
        p,
        landed - p,
        s,
        des.info,
        ddir,
        {
            "file": str(vj),
            "sha256": hashlib.sha256(vj.read_bytes()).hexdigest(),
            # the photos measured: a sheet is its photos (one given twice, or a copy, shares them)
            "photos_sha256": sorted(
                {e["sha256"] for e in photos if isinstance(e, dict) and isinstance(e.get("sha256"), str)}
            ),
        },
        film,
    )


def check_distinct_sheets(sheets: list[Sheet]) -> None:
    """No measurement is given twice: one folder named twice, or a copy of one.

    A sheet is its photos (by the sha256 validation.json records of each): the same photo in two
    sheets would read as a perfectly repeatable process (repeatability 0 mm) and weigh that
    sheet's placement double in the profile. (Two sheets formed alike may land alike; two
    photos are never one file.)
    """
    files: dict[str, str] = {}
    photos: dict[str, str] = {}
    for s in sheets:
        for part in s.validation.get("parts") or [s.validation]:
            real = os.path.realpath(part["file"])
            if real in files:
                raise WorkbenchError(f"{part['file']}: given twice (as {files[real]}): give each formed sheet once")
            files[real] = part["file"]
            for h in part.get("photos_sha256") or []:
                if h in photos:
                    raise WorkbenchError(
                        f"{part['file']}: a photo of the sheet of {photos[h]} (sha256 {h[:12]}...): the same "
                        "measurement twice; give each formed sheet once"
                    )
                photos[h] = part["file"]


def _map_sha256(design_dir: Path) -> str | None:
    """The hash of a design's map of the surface to the print (``flat.obj``); None when missing."""
    path = Path(design_dir) / "flat.obj"
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None


def check_same_design(sheets: list[Sheet]) -> None:
    """All sheets are validations of one design: the first's.

    One design for forming is one mesh, print, dpi, films, compensation and map of the surface
    (``flat.obj``): two designs that share all of these and differ in their artwork are one, since
    forming moves the film whatever is printed on it. (Before, the map was not compared: another
    design of the same mesh, print and dpi, with other corners, was taken for the same.)
    """
    ref = sheets[0]
    maps: dict[str, str | None] = {}  # (sheets share their design folder: each flat.obj hashed once)
    for s in (ref, *sheets[1:]):
        key = os.path.realpath(s.design_dir)
        if key not in maps:
            maps[key] = _map_sha256(s.design_dir)
    ref_map = maps[os.path.realpath(ref.design_dir)]
    for s in sheets[1:]:
        a, b = fm.design_identity(ref.design), fm.design_identity(s.design)
        a["map (flat.obj)"], b["map (flat.obj)"] = ref_map, maps[os.path.realpath(s.design_dir)]
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


def _gram(B, w) -> sp.csr_matrix:
    """The weighted normal equations' matrix Bᵀ W B."""
    return (B.T @ sp.diags(w) @ B).tocsr()


def _factor(G, P, lam):
    """The factorisation of the penalised normal equations G + λ P."""
    from scipy.sparse.linalg import splu

    return splu((G + lam * P).tocsc(), permc_spec="MMD_AT_PLUS_A")


class Normals:
    """The weighted normal equations of fixed points, for any subset of them kept and any displacements.

    A fit drops outliers (a few points), alternates with the sheets' placements (new displacements,
    the same points and weights) and cross-validates over folds: the matrix Bᵀ W B over the kept
    points (of a fold) is the whole's (the fold's) less its dropped points', so each costs a sparse
    product over the dropped points only, and each factorisation of Bᵀ W B + λ P is made once per
    kept set and smoothing. On the face mask's two sheets of 1.2 M points this is most of the time
    saved.

    Parameters
    ----------
    B : (n, m) csr
        The basis at the points (:meth:`Spline2D.design`).
    w : (n,) float
        Each point's weight, 1 / σ² (mm⁻²).
    fold : (n,) int
        Each point's cross-validation fold (0 .. CV_FOLDS - 1).
    """

    def __init__(self, B: sp.csr_matrix, w: np.ndarray, fold: np.ndarray):
        self.B, self.w, self.fold = B, w, fold
        self.BT = B.T.tocsr()
        self.whole = _gram(B, w)
        # (the folds' own are made when cross-validation first asks: a refit at a known smoothing does not)
        self._folds: list | None = None
        self._lu: dict = {}

    def _less(self, G, drop):
        return (G - _gram(self.B[drop], self.w[drop])).tocsr() if drop.any() else G

    def matrix(self, keep: np.ndarray, fold: int | None = None) -> sp.csr_matrix:
        """Bᵀ W B over the kept points (of one fold when ``fold`` is given)."""
        if fold is None:
            return self._less(self.whole, ~keep)
        if self._folds is None:
            self._folds = [_gram(self.B[self.fold == f], self.w[self.fold == f]) for f in range(CV_FOLDS)]
        return self._less(self._folds[fold], ~keep & (self.fold == fold))

    def rhs(self, keep: np.ndarray, d: np.ndarray, fold: int | None = None) -> np.ndarray:
        """Bᵀ W d over the kept points (of one fold): (m, 2)."""
        on = keep if fold is None else keep & (self.fold == fold)
        return self.BT @ ((self.w * on)[:, None] * d)

    def solve(self, keep: np.ndarray, d: np.ndarray, P: sp.csr_matrix, lam: float) -> np.ndarray:
        """The penalised fit's coefficients (m, 2) to the kept points' displacements ``d`` (n, 2)."""
        key = (hashlib.sha1(np.packbits(keep).tobytes()).hexdigest(), float(lam))
        lu = self._lu.get(key)
        if lu is None:
            if len(self._lu) > 8:  # (kept sets and smoothings go by; the newest are reused)
                self._lu.clear()
            lu = self._lu[key] = _factor(self.matrix(keep), P, lam)
        return lu.solve(np.ascontiguousarray(self.rhs(keep, d)))


def cv_folds(p: np.ndarray) -> np.ndarray:
    """Each point's cross-validation fold: squares of CV_BLOCK_MM, neighbours correlated. (n,) int."""
    cell = np.floor(p / CV_BLOCK_MM).astype(np.int64)
    return (cell[:, 0] * 7 + cell[:, 1] * 3) % CV_FOLDS


def fit_field(basis: Spline2D, p, d, sigma, lam: float | None = None, normals: Normals | None = None):
    """Penalised least squares of d(p) on the basis, outliers dropped; smoothing by blocked CV when ``lam`` is None.

    ``normals``: the points' :class:`Normals` (the same p and sigma), kept by a caller that fits
    the same points again (new displacements, another smoothing).

    Returns
    -------
    coef : (nx * ny, 2) float
    lam : float
        The smoothing used (absolute: times the penalty).
    info : dict
        ``cv_rms_mm``, ``fit_rms_mm``, ``points``, ``outliers``, ``keep`` (n,) bool.
    """
    s = np.maximum(sigma, MIN_SIGMA_MM)
    if normals is None:
        normals = Normals(basis.design(p), 1.0 / s**2, cv_folds(p))
    B, w, fold = normals.B, normals.w, normals.fold
    P = basis.penalty()
    scale = float(w.sum()) / max(P.shape[0], 1)  # λ relative to the data's total weight per coefficient
    keep = np.ones(len(p), bool)

    def drop_outliers(keep, lam_abs):
        for _ in range(3):
            c = normals.solve(keep, d, P, lam_abs)
            z = np.linalg.norm(B @ c - d, axis=1) / s
            # (beyond OUTLIER_Z standard uncertainties, or far beyond the typical residual where the
            # uncertainties are optimistic)
            new = z <= max(OUTLIER_Z * np.sqrt(2.0), 4.0 * float(np.median(z[keep])))
            if new.sum() < MIN_POINTS or (new == keep).all():
                return keep, c
            keep = new
        return keep, c

    def cross_validate(keep, candidates):
        # candidates: indices into LAMBDAS; returns the best one's index and its RMS. A fold's training
        # equations are the whole's less its own: made once, not once per smoothing
        G, rhs = normals.matrix(keep), normals.rhs(keep, d)
        tests = [keep & (fold == f) for f in range(CV_FOLDS)]
        folds = [f for f in range(CV_FOLDS) if tests[f].any() and (keep & (fold != f)).sum() >= 16]
        train = {f: (G - normals.matrix(keep, f), rhs - normals.rhs(keep, d, f)) for f in folds}
        Bt = [B[tests[f]] for f in range(CV_FOLDS)]

        def held_out(job):
            rl, f = job
            c = _factor(train[f][0], P, rl * scale).solve(np.ascontiguousarray(train[f][1]))
            r = Bt[f] @ c - d[tests[f]]
            return float((w[tests[f]][:, None] * r * r).sum()), float((r * r).sum()), int(tests[f].sum())

        # the factorisations are nearly all of the time, and SuperLU lets go of the interpreter: one
        # thread per core; the sums are taken in the folds' order, so the result does not depend on it
        jobs = [(rl, f) for rl in LAMBDAS[candidates] for f in folds]
        with ThreadPoolExecutor(max(1, min(2, os.cpu_count() or 1))) as ex:
            got = list(ex.map(held_out, jobs))
        errs, rms = [], []
        for k in range(len(candidates)):
            part = got[k * len(folds) : (k + 1) * len(folds)]
            errs.append(sum(g[0] for g in part))
            rms.append(np.sqrt(sum(g[1] for g in part) / max(sum(g[2] for g in part), 1)))
        best = int(np.argmin(errs))
        return int(candidates[best]), float(rms[best])

    every_other = np.arange(0, len(LAMBDAS), 2)

    cv = None
    if lam is None:
        # every other candidate (the outliers' smoothing needs no more), and without them every
        # other again, then the two beside the best: the error is one valley over log λ, and a
        # factorisation per candidate and fold is nearly all of the time
        i, _ = cross_validate(keep, every_other)
        keep, _ = drop_outliers(keep, float(LAMBDAS[i] * scale))
        i, _ = cross_validate(keep, every_other)
        i, cv = cross_validate(keep, np.arange(max(0, i - 1), min(len(LAMBDAS), i + 2)))
        lam = float(LAMBDAS[i] * scale)
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


def linear_coef(basis: Spline2D, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The basis coefficients of the linear field f(x, y) = a + b x + c y (each (2,): its two components).

    Clamped cubic B-splines reproduce linear functions exactly: the coefficient of x is the
    Greville abscissa of its basis function (the mean of its three inner knots).
    """
    gx = (basis.tx[1:-3] + basis.tx[2:-2] + basis.tx[3:-1]) / 3.0
    gy = (basis.ty[1:-3] + basis.ty[2:-2] + basis.ty[3:-1]) / 3.0
    X, Y = np.meshgrid(gx, gy, indexing="ij")  # (nx, ny), column i * ny + j
    return (a[None, :] + X.reshape(-1, 1) * b[None, :] + Y.reshape(-1, 1) * c[None, :]).astype(np.float64)


def rigid_coef(basis: Spline2D, t: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Coefficients of the first-order rigid field t + ω J (p - c) (``t``: tx, ty, ω): linear, so exact."""
    tx, ty, w = t
    # d = (tx - ω (y - cy), ty + ω (x - cx))
    a = np.array([tx + w * centre[1], ty - w * centre[0]])
    return linear_coef(basis, a, np.array([0.0, w]), np.array([-w, 0.0]))


def rigid_at(t: np.ndarray, p: np.ndarray, centre: np.ndarray) -> np.ndarray:
    x = p - centre
    return np.stack([t[0] - t[2] * x[:, 1], t[1] + t[2] * x[:, 0]], axis=1)


def fit_sheets(basis: Spline2D, parts: list, centre: np.ndarray, lam: float | None = None):
    """One smooth field D and each sheet's placement deviation, fitted to the sheets' points together.

    d_s(p) = D(p) + t_s + ω_s J (p - c), the deviations summing to zero over the sheets. By
    alternation: D fitted to the points less their sheet's deviation, then each sheet's
    deviation fitted to its residual (weighted least squares), centred over the sheets; rigid
    fields lie in the spline's space, so a few rounds converge. The smoothing is chosen by
    cross-validation on the points less their placements (a sheet's placement is not noise
    about D, and would over-smooth it).

    Parameters
    ----------
    basis : Spline2D
    parts : list of ((n_s, 2), (n_s, 2), (n_s,)) float
        Each sheet's points p, displacements d and uncertainties.
    centre : (2,) float
        The placements' turning centre, mm.
    lam : float, optional
        The smoothing (None: cross-validated).

    Returns
    -------
    coef : (nx * ny, 2) float
        D's coefficients (the sheets' mean placement included).
    lam : float
    info : dict
        As :func:`fit_field`'s, and ``deviation`` (n_sheets, 3): each sheet's tx, ty (mm), ω (rad)
        about the mean; ``keep`` per point of the concatenation.
    """
    n = len(parts)
    sizes = [len(x[0]) for x in parts]
    cut = np.cumsum([0, *sizes])
    p = np.concatenate([x[0] for x in parts])
    d = np.concatenate([x[1] for x in parts])
    sig = np.concatenate([x[2] for x in parts])
    w = 1.0 / np.maximum(sig, MIN_SIGMA_MM) ** 2
    dev = np.zeros((n, 3))
    normals = Normals(basis.design(p), w, cv_folds(p))  # (every fit below is of these points)
    if n == 1:
        coef, chosen, info = fit_field(basis, p, d, sig, lam, normals)
        info["deviation"] = dev
        return coef, chosen, info

    def shifted():
        return d - np.concatenate([rigid_at(dev[s], parts[s][0], centre) for s in range(n)])

    def alternate(lam_abs):
        nonlocal dev
        for _ in range(PLACEMENT_ITERATIONS):
            coef, _, info = fit_field(basis, p, shifted(), sig, lam_abs, normals)
            r = shifted() - normals.B @ coef
            keep = info["keep"]
            inc = np.array(
                [
                    fm.fit_rigid(p[a:b][keep[a:b]], r[a:b][keep[a:b]], w[a:b][keep[a:b]], centre)
                    if keep[a:b].sum() >= 3
                    else np.zeros(3)
                    for a, b in zip(cut[:-1], cut[1:], strict=True)
                ]
            )
            inc -= inc.mean(axis=0)
            dev = dev + inc
            # (a turn of ω moves the film by ω r: 1e-5 mm at 500 mm from the centre)
            if max(np.abs(inc[:, :2]).max(), np.abs(inc[:, 2]).max() * 500.0) < PLACEMENT_TOL_MM:
                break

    # the placements first, at a middling smoothing (they are the film's largest scale: any smoothing
    # sees them alike), then the smoothing cross-validated on the points less their placements, and
    # the placements again at it
    cv = None
    if lam is None:
        alternate(10.0 * float(w.sum()) / np.prod(basis.shape))
        _, lam, cvinfo = fit_field(basis, p, shifted(), sig, None, normals)
        cv = cvinfo["cv_rms_mm"]
    alternate(lam)
    coef, chosen, info = fit_field(basis, p, shifted(), sig, lam, normals)
    info["cv_rms_mm"] = cv
    info["deviation"] = dev
    return coef, chosen, info


def placement_test(m: np.ndarray, dev: np.ndarray, mode: str = "auto") -> dict:
    """Is the sheets' mean placement ``m`` (tx, ty, ω) systematic, beyond their random placements ``dev``?

    The deviations about the mean give the placement's spread: per axis for the shift (both axes
    pooled, 2 (n - 1) degrees of freedom), and for the turn (n - 1). The mean's standard error is
    the spread / √n; the shift is systematic when n |m_t|² / (2 s_t²) exceeds F(2, 2 (n - 1)) at
    PLACEMENT_LEVEL, the turn when n ω² / s_ω² exceeds F(1, n - 1). ``mode``: "auto" (the
    default) compensates what the test finds systematic, "always" the whole mean, "never" none of it.
    """
    from scipy.stats import f as fisher

    n = len(dev)
    out: dict = {"sheets": n}
    if n > 1:
        st = float(np.sqrt((dev[:, :2] ** 2).sum() / (2 * (n - 1))))
        sw = float(np.sqrt((dev[:, 2] ** 2).sum() / (n - 1)))
        ft = n * float(m[0] ** 2 + m[1] ** 2) / (2 * st * st) if st > 0 else np.inf
        fw = n * float(m[2] ** 2) / (sw * sw) if sw > 0 else np.inf
        sig_t = bool(ft > fisher.ppf(PLACEMENT_LEVEL, 2, 2 * (n - 1)))
        sig_w = bool(fw > fisher.ppf(PLACEMENT_LEVEL, 1, n - 1))
        out.update(
            spread_mm=st,
            rotation_spread_deg=float(np.degrees(sw)),
            standard_error_mm=st / np.sqrt(n),
            rotation_standard_error_deg=float(np.degrees(sw / np.sqrt(n))),
            systematic={"shift": sig_t, "rotation": sig_w},
        )
    else:
        sig_t = sig_w = True  # one sheet: nothing to test against
        out["systematic"] = None
    on = {"auto": (sig_t, sig_w), "always": (True, True), "never": (False, False)}[mode]
    out["mode"] = mode
    out["compensated_parts"] = {"shift": on[0], "rotation": on[1]}
    return out


@dataclass
class FilmGrid:
    """A film's points on a 1 mm grid of its uncompensated print, and its outline there.

    Attributes
    ----------
    points : (n, 2) float
        Grid points on the film as printed (this design's outline, mm on the uncompensated print).
    on_part : callable (m, 2) -> (m,) bool
        Whether points of the uncompensated print lie on the part (inside the outline the
        design's map gives the film: where a film point that lands there is decorated).
    """

    points: np.ndarray
    on_part: object


def design_of(design_dir: Path, designs: dict | None = None):
    """The design folder read, or taken from ``designs`` (path to Design) where it was read before."""
    from workbench.design_dir import Design

    if designs is None:
        return Design(design_dir)
    key = Path(os.path.realpath(design_dir))
    if key not in designs:
        designs[key] = Design(design_dir)
    return designs[key]


def film_grids(design_dir: Path, spacing_mm: float = 1.0, designs: dict | None = None) -> list[FilmGrid]:
    """Each film's grid points (as printed) and its outline on the part, on its uncompensated print."""
    from workbench.texture.outline import film_mask

    des = design_of(design_dir, designs)
    nominal = des.nominal_print_mm()
    vf = des.vertex_films()
    films = des.info.get("films") or []
    ppm = des.info["print"]["dpi"] / 25.4
    out = []
    for k, fr in enumerate(des.film_frames()):
        W, H = fr.size_mm
        xs = np.arange(0.5 * spacing_mm, fr.print_mm[0], spacing_mm)
        ys = np.arange(0.5 * spacing_mm, fr.print_mm[1], spacing_mm)
        # the film as printed, in its own print, then on its uncompensated print
        g = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2) + fr.corner_mm
        if des.alpha is not None:
            ij = np.floor(g * ppm).astype(int)
            h, w = des.alpha.shape
            inside = (ij[:, 0] >= 0) & (ij[:, 0] < w) & (ij[:, 1] >= 0) & (ij[:, 1] < h)
            on = np.zeros(len(g), bool)
            on[inside] = des.alpha[ij[inside, 1], ij[inside, 0]] > 0
            g = g[on]
        # the film's outline on the part: its faces at their nominal (uncompensated) positions
        faces = des.F if not films else des.F[slice(*films[k]["atlas_faces"])]
        scale = 4.0  # px per mm of the outline's raster
        lo = np.array([-20.0, -20.0])
        shape = (int(np.ceil((H + 40) * scale)), int(np.ceil((W + 40) * scale)))
        P = (np.where(np.isfinite(nominal), nominal, 0.0) - lo) * scale - 0.5
        mask = film_mask(P, faces, *shape) if (vf == k).any() else np.ones(shape, bool)

        def on_part(x, mask=mask, lo=lo, scale=scale):
            ij = np.floor((np.asarray(x) - lo) * scale).astype(int)
            inside = (ij[:, 0] >= 0) & (ij[:, 0] < mask.shape[1]) & (ij[:, 1] >= 0) & (ij[:, 1] < mask.shape[0])
            res = np.zeros(len(ij), bool)
            res[inside] = mask[ij[inside, 1], ij[inside, 0]]
            return res

        out.append(FilmGrid(g - fr.origin_mm, on_part))
    return out


def film_where(sheet: Sheet, k: int, name: str) -> str:
    return sheet.validation["file"] + (f": film {name}" if len(sheet.design.get("films") or []) > 1 else "")


def calibrate_film(sheets: list[Sheet], k: int, size_mm, grid: FilmGrid, placement: str = "auto") -> dict:
    """Film ``k``'s profile from the sheets: its deformation, mean placement, spread and coverage.

    Returns
    -------
    dict
        ``field`` (SplineField: the deformation, without the mean placement), ``applied`` (what
        compensation uses: the field plus the compensated part of the placement), ``placement``
        (dict), ``smoothing``, ``cv_rms_mm``, ``fit_rms_mm``, ``points``, ``outliers``,
        ``repeatability_mm`` (the sheets' spread about the profile, None with one sheet),
        ``deformation_repeatability_mm`` (the same, each sheet's placement removed), ``per_sheet``,
        ``measured_share`` (of the film as printed), ``measured_share_on_part`` (of the film
        that lands on the part), ``extrapolated_share`` (and ``_on_part``), ``max_extrapolation_mm``,
        ``extrapolated_at_mm``, ``grid``, ``measured``, ``points_mm``, ``warnings``, ``size_mm``.
    """
    W, H = size_mm
    name = (sheets[0].design.get("films") or [{"name": "film-1"}])[k]["name"]
    parts = [s.of_film(k) for s in sheets]
    for s, (p, _, _) in zip(sheets, parts, strict=True):
        if len(p) < MIN_POINTS:
            where = ""
            if len(p):
                lo, hi = p.min(axis=0), p.max(axis=0)
                where = f", all within x {lo[0]:.0f} to {hi[0]:.0f} mm, y {lo[1]:.0f} to {hi[1]:.0f} mm of the print"
            raise WorkbenchError(
                f"{film_where(s, k, name)}: {len(p)} measured points on the film{where}; a forming profile needs at "
                f"least {MIN_POINTS}: photograph the sheet from its designed views, or print the calibration film "
                "(workbench pdf DESIGN --pattern forming)"
            )
    knot = max(KNOT_MM, max(W, H) / KNOTS_ACROSS)
    basis = Spline2D.over((-MARGIN_MM, -MARGIN_MM), (W + MARGIN_MM, H + MARGIN_MM), knot)
    # the placements turn about the measured film's centre
    allp = np.concatenate([x[0] for x in parts])
    centre = np.round(allp.mean(axis=0), 3)
    coef, lam, info = fit_sheets(basis, parts, centre)
    dev = info["deviation"]
    keep = info["keep"]
    g = grid.points
    dist, _ = cKDTree(allp[keep]).query(g) if len(g) else (np.zeros(0), None)
    measured = dist <= 1.0
    # the mean placement: D's rigid part over the measured film (each grid point alike)
    D = basis.field(coef)
    gm = g[measured] if measured.sum() >= 3 else allp[keep]
    m = fm.fit_rigid(gm, D(gm), np.ones(len(gm)), centre)
    test = placement_test(m, dev, placement)
    deform = basis.field(coef - rigid_coef(basis, m, centre))
    on = test["compensated_parts"]
    applied_t = np.array([m[0], m[1], 0.0]) * on["shift"] + np.array([0.0, 0.0, m[2]]) * on["rotation"]
    applied = basis.field(coef - rigid_coef(basis, m - applied_t, centre))
    pl = {
        "shift_mm": [float(m[0]), float(m[1])],
        "rotation_deg": float(np.degrees(m[2])),
        "centre_mm": centre.tolist(),
        **test,
        # each sheet's placement (the mean plus its deviation): what validate's film offset sees of it
        "per_sheet": [[float(m[0] + v[0]), float(m[1] + v[1]), float(np.degrees(m[2] + v[2]))] for v in dev],
    }
    # a profile applies shift and turn together: a part left out is zeroed in what is recorded as applied
    pl["compensated"] = bool(on["shift"] or on["rotation"])
    pl["applied"] = {
        "shift_mm": [float(applied_t[0]), float(applied_t[1])],
        "rotation_deg": float(np.degrees(applied_t[2])),
    }
    per_sheet, fields, fields_deform = [], [], []
    for (p, d, sg), v in zip(parts, dev, strict=True):
        c, _, _ = fit_field(basis, p, d, sg, lam)
        fields.append(basis.field(c))
        fields_deform.append(basis.field(c - rigid_coef(basis, v, centre)))
        r = applied(p) - d
        per_sheet.append(
            {
                "points": int(len(p)),
                "residual_rms_mm": float(np.sqrt((r * r).sum(1).mean())),
                "placement": {
                    "shift_mm": [float(m[0] + v[0]), float(m[1] + v[1])],
                    "rotation_deg": float(np.degrees(m[2] + v[2])),
                },
            }
        )
    landed = fm.land(applied, g) if len(g) else g
    on_part = grid.on_part(landed) if len(g) else np.zeros(0, bool)
    far = dist > EXTRAPOLATION_MM
    rep = rep_deform = None
    if len(sheets) > 1 and measured.any():
        # the sheets' fields where they were all measured: their spread per axis about the mean
        common = g[measured]
        for fs, key in ((fields, "all"), (fields_deform, "deform")):
            vals = np.stack([f(common) for f in fs])  # (sheets, n, 2)
            spread = float(np.sqrt(vals.var(axis=0, ddof=1).mean()))
            if key == "all":
                rep = spread
            else:
                rep_deform = spread
    warnings = []
    far_share = float(far.mean()) if len(g) else 0.0
    far_on_part = float(far[on_part].mean()) if on_part.any() else 0.0
    at = g[np.argmax(dist)].tolist() if len(g) else None
    films_of = len(sheets[0].design.get("films") or []) > 1
    if far_on_part > EXTRAPOLATION_WARN_SHARE:
        worst = g[on_part][np.argmax(dist[on_part])]
        warnings.append(
            ("" if not films_of else f"film {name}: ")
            + f"{100 * far_on_part:.1f} % of the film that lands on the part lies more than {EXTRAPOLATION_MM:g} mm "
            f"from a measured point (up to {dist[on_part].max():.1f} mm, at ({worst[0]:.0f}, {worst[1]:.0f}) mm on the "
            "print): the profile extrapolates there (linearly); photograph the sheets from more views or print the "
            "calibration film"
        )
    dmag = np.linalg.norm(deform(g), axis=1) if len(g) else np.zeros(1)
    return {
        "name": name,
        "field": deform,
        "applied": applied,
        "placement": pl,
        "sheet_fields": fields,
        "smoothing": lam,
        **{k2: v for k2, v in info.items() if k2 not in ("keep", "deviation")},
        "repeatability_mm": rep,
        "deformation_repeatability_mm": rep_deform,
        "per_sheet": per_sheet,
        "measured_share": float(measured.mean()) if len(g) else 0.0,
        # of the film that lands on the part (by the profile, inside the film's outline on the part): a film
        # that slides outwards at the rim puts its outer band beyond the part, where no photo can see it and
        # where compensation never looks (it asks which film point lands on each point of the part)
        "measured_share_on_part": float(measured[on_part].mean()) if on_part.any() else 0.0,
        "on_part_share": float(on_part.mean()) if len(g) else 0.0,
        "extrapolated_share": far_share,
        "extrapolated_share_on_part": far_on_part,
        "max_extrapolation_mm": float(dist.max()) if len(g) else None,
        "extrapolated_at_mm": at,
        "d_median_mm": float(np.median(dmag)),
        "d_p95_mm": float(np.percentile(dmag, 95)),
        "d_max_mm": float(dmag.max()),
        "grid": g,
        "on_part": grid.on_part,
        "measured": measured,
        "points_mm": allp[keep],
        "warnings": warnings,
        "size_mm": (W, H),
    }


def calibrate_forming(sheets: list[Sheet], placement: str = "auto", designs: dict | None = None) -> dict:
    """The forming profile's numbers from the sheets: one :func:`calibrate_film` per film.

    ``designs``: the design folders read so far (:func:`read_sheet`).

    Returns
    -------
    dict
        ``films``: per film, :func:`calibrate_film`'s dict; ``warnings``: all films'.
    """
    ref = sheets[0]
    designs = {} if designs is None else designs  # (read once here, whoever calls)
    frames = design_of(ref.design_dir, designs).film_frames()
    grids = film_grids(ref.design_dir, designs=designs)
    films = [calibrate_film(sheets, k, fr.size_mm, grids[k], placement) for k, fr in enumerate(frames)]
    return {"films": films, "warnings": [w for f in films for w in f["warnings"]]}


def profile_picture(result: dict, title: str) -> bytes:
    """Each film's deformation over its print: |d| in colour, arrows (magnified), the film not measured
    (shaded) and where the profile extrapolates (dark), the part's outline; one panel per film."""
    from workbench.figures import figure_png

    return figure_png(profile_plot(result, title))


def profile_plot(result: dict, title: str):
    """:func:`profile_picture`'s figure: one panel per film, each in mm from that film's top-left corner,
    y down (:func:`workbench.figures.print_axes`)."""
    from workbench.figures import _figure, print_axes, print_extent

    plt = _figure()
    films = result["films"]
    n = len(films)
    cols = min(n, 2)
    rows = (n + cols - 1) // cols
    aspect = max(f["size_mm"][1] / f["size_mm"][0] for f in films)
    width = 9.0 if n == 1 else 6.0 * cols
    fig, axes = plt.subplots(rows, cols, figsize=(width, rows * (width / cols) * 0.75 * aspect + 1.2), dpi=110,
                             layout="constrained", squeeze=False)  # fmt: skip
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    for ax, res in zip(axes.ravel(), films, strict=False):
        W, H = res["size_mm"]
        xs = np.linspace(0, W, 241)
        ys = np.linspace(0, H, max(2, int(241 * H / W)))
        g = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
        d = res["field"](g).reshape(len(ys), len(xs), 2)
        mag = np.linalg.norm(d, axis=2)
        # (the colours and arrows of the film on the part: beyond it the field only extrapolates)
        part = res["on_part"](g).reshape(len(ys), len(xs)) if "on_part" in res else np.ones(mag.shape, bool)
        top = float(mag[part].max()) if part.any() else float(mag.max())
        im = ax.imshow(mag, extent=print_extent(W, H), cmap="viridis", origin="upper", vmin=0.0, vmax=top or None)
        fig.colorbar(im, ax=ax, label="|d| (mm)", shrink=0.8)
        step = max(1, len(xs) // 24)
        sub = g.reshape(len(ys), len(xs), 2)[::step, ::step].reshape(-1, 2)
        dv = d[::step, ::step].reshape(-1, 2)
        on = part[::step, ::step].reshape(-1)
        k = 0.8 * W / 24 / (top or 1.0)
        ax.quiver(sub[on, 0], sub[on, 1], dv[on, 0] * k, dv[on, 1] * k, angles="xy", scale_units="xy", scale=1,
                  color="white")  # fmt: skip
        # the film nothing measured (grey), where the profile extrapolates (darker), and beyond the
        # film's outline on the part (white: compensation never looks there)
        dist, _ = cKDTree(res["points_mm"]).query(g)
        dist = dist.reshape(len(ys), len(xs))
        shade = np.zeros((len(ys), len(xs), 4))
        shade[..., 3] = np.where(dist > EXTRAPOLATION_MM, 0.6, np.where(dist > 1.0, 0.3, 0.0))
        shade[~part] = [1.0, 1.0, 1.0, 0.85]
        ax.imshow(shade, extent=print_extent(W, H), origin="upper")
        print_axes(ax, W, H, "film")
        pl = res["placement"]
        ax.set_title(
            (f"{res['name']}: " if n > 1 else "")
            + f"arrows x {k:.1f}; measured {100 * res['measured_share_on_part']:.1f} % of the film on the part "
            f"({100 * res['measured_share']:.1f} % of the film)\nmean placement ({pl['shift_mm'][0]:.3f}, "
            f"{pl['shift_mm'][1]:.3f}) mm, {pl['rotation_deg']:.4f}°, "
            + ("compensated" if pl["compensated"] else "not compensated")
            + " (not in the field shown)",
            fontsize=8,
        )
    fig.suptitle(
        title + f"\nshaded: the film not measured; dark: more than {EXTRAPOLATION_MM:g} mm from a measurement; "
        "white: beyond the film's outline on the part",
        fontsize=9,
    )
    return fig

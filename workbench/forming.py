"""How a formed film really lands: displacement fields d(p) on the print.

Forming moves the film point printed at p (print mm of the uncompensated film, x right,
y down from the trim's top-left corner) to the surface point the design's map puts at
``q = p + d(p)``. The conformal map is the hypothesis d = 0; a forming law (for the tests'
truth) or a measured forming profile (``workbench calibrate forming``) is a smooth d.
A design of several films has one field per film, each on that film's own print (films
are formed one by one: each deforms and is placed on its own).

Every field here is a callable ``field(p) -> d``, ``p`` and ``d`` of shape (n, 2) float64,
mm. Two kinds:

- :class:`AnalyticLaw`: named smooth non-conformal laws with parameters, parsed from
  ``KIND:A,B[,...]`` terms joined by ``+`` (``creep:2,1.5+wave:0.5,0.5,40``);
- :class:`SplineField`: a tensor-product cubic B-spline (what a profile holds).

Pure functions; the commands read and write the files.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline

from workbench.errors import WorkbenchError

# the laws and their parameters (amplitudes in mm at the print's edge; u, v in [-1, 1] across it)
LAWS = {
    # anisotropic stretch, uniform: d = (SX u, SY v); non-conformal unless SX / W = SY / H
    "stretch": ("SX", "SY"),
    # anisotropic creep: the film slides most at the rim, more along one direction (extruded sheet):
    # d = (AX u³, AY v³)
    "creep": ("AX", "AY"),
    # draw-dependent stretch of a dome: the film is drawn outwards most half-way to the rim:
    # d = A (u, v) (1 - (u² + v²) / 2)
    "draw": ("A",),
    # shear wave of wavelength L mm: d = (AX sin(2π y / L), AY sin(2π x / L))
    "wave": ("AX", "AY", "L"),
    # a rigid shift: d = (DX, DY)
    "shift": ("DX", "DY"),
}


@dataclass(frozen=True)
class AnalyticLaw:
    """A sum of named laws over a print of ``size_mm``.

    Attributes
    ----------
    terms : tuple of (str, tuple of float)
        Each law's name and parameters.
    size_mm : (2,) float
        Width and height of the (uncompensated) print, mm: the laws' u, v run from -1 to 1 across it.
    """

    terms: tuple
    size_mm: tuple

    def __call__(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
        a, b = 0.5 * self.size_mm[0], 0.5 * self.size_mm[1]
        u, v = (p[:, 0] - a) / a, (p[:, 1] - b) / b
        d = np.zeros_like(p)
        for kind, k in self.terms:
            if kind == "stretch":
                d += np.stack([k[0] * u, k[1] * v], axis=1)
            elif kind == "creep":
                d += np.stack([k[0] * u**3, k[1] * v**3], axis=1)
            elif kind == "draw":
                w = k[0] * (1.0 - 0.5 * (u * u + v * v))
                d += np.stack([w * u, w * v], axis=1)
            elif kind == "wave":
                d += np.stack(
                    [k[0] * np.sin(2 * np.pi * p[:, 1] / k[2]), k[1] * np.sin(2 * np.pi * p[:, 0] / k[2])], axis=1
                )
            elif kind == "shift":
                d += np.asarray(k[:2])
        return d


def parse_law(spec: str, size_mm, where: str = "--forming") -> AnalyticLaw:
    """``KIND:A,B[,...]`` terms joined by ``+`` (see :data:`LAWS`); one clear error otherwise."""
    terms = []
    for term in spec.split("+"):
        kind, _, rest = term.strip().partition(":")
        if kind not in LAWS:
            raise WorkbenchError(
                f"{where} {spec!r}: unknown law {kind!r} (laws: "
                + ", ".join(f"{k}:{','.join(v)}" for k, v in LAWS.items())
                + "; or a forming profile .json)"
            )
        try:
            vals = tuple(float(x) for x in rest.split(",")) if rest.strip() else ()
        except ValueError:
            vals = None
        if vals is None or len(vals) != len(LAWS[kind]) or not all(np.isfinite(vals)):
            raise WorkbenchError(f"{where} {spec!r}: {kind} takes {','.join(LAWS[kind])} (finite numbers)")
        if any(abs(x) > 1000 for x in vals) or (kind == "wave" and not vals[2] > 0):
            raise WorkbenchError(f"{where} {spec!r}: {kind}: amplitudes within ±1000 mm, a wavelength above 0")
        terms.append((kind, vals))
    return AnalyticLaw(tuple(terms), (float(size_mm[0]), float(size_mm[1])))


@dataclass(frozen=True)
class SplineField:
    """A tensor-product cubic B-spline field over a rectangle, constant beyond it.

    Attributes
    ----------
    tx, ty : (nx + 4,), (ny + 4,) float
        Knots along x and y, mm (clamped: the end knots repeated four times).
    coef : (nx, ny, 2) float
        Coefficients of d_x and d_y, mm.
    """

    tx: np.ndarray
    ty: np.ndarray
    coef: np.ndarray

    def basis(self, p: np.ndarray):
        """The B-spline design matrices along x and y at ``p`` (clamped to the domain)."""
        p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
        x = np.clip(p[:, 0], self.tx[3], self.tx[-4] - 1e-9)
        y = np.clip(p[:, 1], self.ty[3], self.ty[-4] - 1e-9)
        return BSpline.design_matrix(x, self.tx, 3), BSpline.design_matrix(y, self.ty, 3)

    def __call__(self, p: np.ndarray) -> np.ndarray:
        if not len(np.asarray(p).reshape(-1, 2)):
            return np.zeros((0, 2))
        Bx, By = (b.tocsr() for b in self.basis(p))
        # d(p) = Σ_ij Bx_i(x) By_j(y) c_ij, over the 4 x 4 basis functions not zero at p (each
        # row of a cubic design matrix holds 4: dense rows cost n · nx · ny, a 300 mm film's
        # 100 k points a third of a second per call)
        ix, iy = Bx.indices.reshape(-1, 4), By.indices.reshape(-1, 4)
        w = Bx.data.reshape(-1, 4)[:, :, None] * By.data.reshape(-1, 4)[:, None, :]
        return (w[..., None] * self.coef[ix[:, :, None], iy[:, None, :]]).sum(axis=(1, 2))

    def to_dict(self) -> dict:
        return {
            "kind": "cubic B-spline, tensor product, clamped knots; constant beyond the knots' range",
            "knots_x_mm": np.round(self.tx, 9).tolist(),
            "knots_y_mm": np.round(self.ty, 9).tolist(),
            "coef_mm": np.round(self.coef, 7).tolist(),
        }

    @classmethod
    def from_dict(cls, d: dict, where: str) -> SplineField:
        try:
            tx = np.asarray(d["knots_x_mm"], dtype=np.float64)
            ty = np.asarray(d["knots_y_mm"], dtype=np.float64)
            coef = np.asarray(d["coef_mm"], dtype=np.float64)
        except (KeyError, TypeError, ValueError):
            raise WorkbenchError(f"{where}: field: knots_x_mm, knots_y_mm and coef_mm expected") from None
        if (
            tx.ndim != 1
            or ty.ndim != 1
            or coef.shape != (len(tx) - 4, len(ty) - 4, 2)
            or not (np.isfinite(tx).all() and np.isfinite(ty).all() and np.isfinite(coef).all())
            or (np.diff(tx) < 0).any()
            or (np.diff(ty) < 0).any()
        ):
            raise WorkbenchError(
                f"{where}: field: coef_mm must be (len(knots_x_mm) - 4, len(knots_y_mm) - 4, 2), finite"
            )
        return cls(tx, ty, coef)


@dataclass(frozen=True)
class Sum:
    """Two fields' sum (a law and a per-sheet rigid placement)."""

    a: object
    b: object

    def __call__(self, p):
        return self.a(p) + self.b(p)


@dataclass(frozen=True)
class Placement:
    """A rigid film placement error: shift (mm) and rotation (rad) about ``centre_mm``."""

    shift_mm: tuple
    rotation_rad: float
    centre_mm: tuple

    def __call__(self, p):
        p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
        c = np.asarray(self.centre_mm)
        t = self.rotation_rad
        R = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
        return (p - c) @ R.T + c - p + np.asarray(self.shift_mm)


def fit_rigid(p: np.ndarray, r: np.ndarray, w: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The rigid motion (small rotation) that best explains the displacements ``r`` at ``p``.

    Weighted least squares of r ≈ t + ω J (p - c), J the quarter turn (x, y) → (-y, x):
    a film placement (shift and turn about ``centre``) to first order.

    Parameters
    ----------
    p, r : (n, 2) float
        Points and their displacements, mm.
    w : (n,) float
        Weights (1 / variance).
    centre : (2,) float
        The turn's centre, mm.

    Returns
    -------
    (3,) float
        tx, ty (mm) and ω (rad).
    """
    x = np.asarray(p, np.float64) - centre
    # rows of the 2n x 3 design matrix, x and y components interleaved
    A = np.zeros((len(x), 2, 3))
    A[:, 0, 0] = 1.0
    A[:, 1, 1] = 1.0
    A[:, 0, 2] = -x[:, 1]
    A[:, 1, 2] = x[:, 0]
    ww = np.repeat(np.asarray(w, np.float64), 2)
    A2 = A.reshape(-1, 3)  # (2n, 3)
    N = A2.T @ (ww[:, None] * A2)
    return np.linalg.solve(N + 1e-12 * np.trace(N) * np.eye(3), A2.T @ (ww * np.asarray(r, np.float64).reshape(-1)))


def rigid_field(t: np.ndarray, centre) -> Placement:
    """``fit_rigid``'s (tx, ty, ω) as a field (the exact turn, not its first order: rotations here are
    thousandths of a radian, where both agree to 1e-6 of the film's size)."""
    return Placement((float(t[0]), float(t[1])), float(t[2]), (float(centre[0]), float(centre[1])))


def zero_field(p):
    return np.zeros((len(np.asarray(p).reshape(-1, 2)), 2))


def land(field, p: np.ndarray) -> np.ndarray:
    """Where print point ``p`` lands: ``p + d(p)``, (n, 2) mm."""
    p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
    return p + field(p)


def invert(field, q: np.ndarray, tol_mm: float = 1e-9, max_iter: int = 200) -> np.ndarray:
    """The print points that land at ``q``: p with p + d(p) = q, (n, 2) mm.

    Fixed-point iteration p ← q - d(p): it converges where the field's Jacobian has norm
    below 1 (a film that does not fold), at that rate; forming fields stretch by a few
    per cent, so a handful of iterations reach round-off.

    Raises
    ------
    WorkbenchError
        The iteration does not converge (a field that folds the film over itself).
    """
    q = np.asarray(q, dtype=np.float64).reshape(-1, 2)
    p = q - field(q)
    for _ in range(max_iter):
        nxt = q - field(p)
        step = float(np.abs(nxt - p).max()) if len(p) else 0.0
        p = nxt
        if step < tol_mm:
            return p
    raise WorkbenchError(
        f"the forming field does not invert (still moving by {step:.3g} mm after {max_iter} steps): "
        "it folds the film over itself"
    )


def compose(outer, inner):
    """The field of forming by ``inner`` then reading through ``outer``: p + d(p) = (id + outer)(p + inner(p))."""

    def field(p):
        p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
        q = p + inner(p)
        return q + outer(q) - p

    return field


def file_sha256(path) -> str:
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def read_profile(path, where: str | None = None) -> dict:
    """A forming profile (``workbench calibrate forming``), checked; each film's applied field as ``_field``.

    A film's applied field is its deformation (``field``) plus its systematic placement when the
    profile compensates it (``placement.compensated``); a profile without ``placement`` (written
    before placements were separated) applies its field as it is.
    """
    where = where or str(path)
    try:
        prof = json.loads(open(path, "rb").read())
    except FileNotFoundError:
        raise WorkbenchError(f"{where}: no such forming profile") from None
    except IsADirectoryError:
        raise WorkbenchError(f"{where}: is a directory, not a forming profile") from None
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise WorkbenchError(f"{where}: not a forming profile (not JSON: {exc})") from None
    if not isinstance(prof, dict) or prof.get("kind") != "forming profile":
        raise WorkbenchError(f"{where}: not a forming profile (kind: 'forming profile' expected)")
    films = prof.get("films")
    if not isinstance(films, list) or not films:
        raise WorkbenchError(f"{where}: films: a list of at least one film expected")
    for k, f in enumerate(films):
        if not isinstance(f, dict) or "field" not in f or not isinstance(f.get("name"), str):
            raise WorkbenchError(f"{where}: films[{k}]: name and field expected")
        field = SplineField.from_dict(f["field"], f"{where}: films[{k}]")
        pl = f.get("placement")
        if pl is not None:
            # what the profile compensates of the sheets' mean placement (calibrate forming's test)
            try:
                shift = tuple(float(x) for x in pl["applied"]["shift_mm"])
                turn = float(np.radians(float(pl["applied"]["rotation_deg"])))
                centre = tuple(float(x) for x in pl["centre_mm"])
            except (KeyError, TypeError, ValueError):
                shift, turn, centre = (), 0.0, ()
            if len(shift) != 2 or len(centre) != 2 or not np.isfinite([*shift, turn, *centre]).all():
                raise WorkbenchError(
                    f"{where}: films[{k}].placement: applied.shift_mm [x, y], applied.rotation_deg and centre_mm "
                    "[x, y] (finite numbers) expected"
                )
            if shift != (0.0, 0.0) or turn != 0.0:
                field = Sum(field, Placement(shift, turn, centre))
        f["_field"] = field
    for key in ("design", "material", "process"):
        if not isinstance(prof.get(key), dict):
            raise WorkbenchError(f"{where}: {key}: missing (an object)")
    return prof


def profile_field(prof: dict, film: int = 0):
    """Film ``film``'s applied field: what compensation and ``render --forming PROFILE`` use."""
    return prof["films"][film]["_field"]


def profile_fields(prof: dict) -> list:
    """Every film's applied field, in the profile's film order."""
    return [f["_field"] for f in prof["films"]]


def film_base_sizes(info: dict) -> list[tuple[float, float]]:
    """Each film's uncompensated print size, mm, from design.json: what its forming field is defined on.

    One film: the print (``forming.base_print`` when compensated); several: each film's record
    (its ``forming.base_print`` when compensated).
    """
    films = info.get("films")
    if not films:
        base = (info.get("forming") or {}).get("base_print") or info["print"]
        return [(float(base["width_mm"]), float(base["height_mm"]))]
    out = []
    for f in films:
        base = (f.get("forming") or {}).get("base_print") or f
        out.append((float(base["width_mm"]), float(base["height_mm"])))
    return out


def design_identity(info: dict) -> dict:
    """What a forming profile must match in a design: its mesh, print rectangle, dpi and films.

    ``info`` is design.json; for a compensated design the uncompensated print's size
    (``forming.base_print``) is the one the profile's field is defined on; with several
    films, each film's uncompensated print (``film_sizes_mm``).
    """
    mesh = next((i for i in info.get("inputs", [])), {})
    sizes = [[round(w, 6), round(h, 6)] for w, h in film_base_sizes(info)]
    out = {
        "mesh_sha256": mesh.get("sha256"),
        "dpi": float(info["print"]["dpi"]),
        "films": [f["name"] for f in info.get("films", [])] or ["film-1"],
    }
    if info.get("films"):
        out["film_sizes_mm"] = sizes
    else:
        out["width_mm"], out["height_mm"] = sizes[0]
    return out


@dataclass
class Compensation:
    """A flat layout pre-compensated for a forming field.

    Attributes
    ----------
    uv : (#V, 2) float
        The compensated layout, mm (y up, the new rectangle's bottom-left at the origin).
    width_mm, height_mm : float
        The new design rectangle (the old one grown by whole pixels where the film needs room).
    frame_offset_px : (2,) int
        The uncompensated grid's origin in the new print's pixels ([x, y]).
    moved_mm : (#V,) float
        How far each vertex moved on the print.
    """

    uv: np.ndarray
    width_mm: float
    height_mm: float
    frame_offset_px: tuple
    moved_mm: np.ndarray


def compensate_layout(uv_mm: np.ndarray, width_mm: float, height_mm: float, dpi: float, field) -> Compensation:
    """Pre-distort a flat layout so that, formed by ``field``, the film lands on the design.

    The surface point the design puts at print position x (a vertex of the layout) must
    show the film point p that lands there: p + d(p) = x. So each vertex moves to p; the
    print's pixels then take the colour of the surface point where they land. The print
    keeps its pixel grid (same dpi, same origin); where p leaves the rectangle the grid
    grows by whole pixels, and ``frame_offset_px`` says where its old origin went.

    Parameters
    ----------
    uv_mm : (#V, 2) float
        Uncompensated layout, mm (y up, bottom-left at the origin).
    width_mm, height_mm : float
        Its rectangle.
    dpi : float
        The print's resolution.
    field : callable
        d(p) on the uncompensated print (mm, x right, y down).

    Returns
    -------
    Compensation
    """
    ppm = dpi / 25.4
    x = np.stack([uv_mm[:, 0], height_mm - uv_mm[:, 1]], axis=1)
    p = invert(field, x)
    lo, hi = p.min(axis=0), p.max(axis=0)
    # (a hair of tolerance: a vertex on the edge that stays there does not grow the print)
    ox, oy = (int(np.ceil(max(0.0, -v) * ppm - 1e-6)) for v in lo)
    cols0, rows0 = int(np.ceil(width_mm * ppm - 1e-9)), int(np.ceil(height_mm * ppm - 1e-9))
    cols = ox + max(cols0, int(np.ceil(hi[0] * ppm - 1e-6)))
    rows = oy + max(rows0, int(np.ceil(hi[1] * ppm - 1e-6)))
    # the rectangle: the old one where nothing needs room, else whole pixels
    w = width_mm if cols == cols0 and ox == 0 else cols / ppm
    h = height_mm if rows == rows0 and oy == 0 else rows / ppm
    q = p + np.array([ox, oy]) / ppm
    return Compensation(
        np.stack([q[:, 0], h - q[:, 1]], axis=1), float(w), float(h), (ox, oy), np.linalg.norm(p - x, axis=1)
    )


def check_profile_for(prof: dict, identity: dict, material: str | None, where: str) -> None:
    """A profile measured for this design (mesh, print rectangle or films' prints, dpi, films) and material;
    one line otherwise. Keys missing from ``identity`` are not checked (the sizes, before the map is known)."""
    d = prof["design"]
    for key, what in (
        ("mesh_sha256", "mesh"),
        ("dpi", "dpi"),
        ("films", "films"),
    ):
        if key in identity and d.get(key) != identity[key]:
            raise WorkbenchError(
                f"{where}: measured for another design: its {what} is {d.get(key)!r}, this job's {identity[key]!r}"
            )
    for key in ("width_mm", "height_mm"):
        if key not in identity:  # (checked again once the map is known)
            continue
        if not abs(float(d.get(key, np.nan)) - identity[key]) <= 1e-3:
            raise WorkbenchError(
                f"{where}: measured for another design: its print is {d.get('width_mm')} x {d.get('height_mm')} mm, "
                f"this job's {identity['width_mm']} x {identity['height_mm']} mm"
            )
    if "film_sizes_mm" in identity:
        got = d.get("film_sizes_mm")
        for k, (name, want) in enumerate(zip(identity["films"], identity["film_sizes_mm"], strict=True)):
            have = got[k] if isinstance(got, list) and k < len(got) and isinstance(got[k], list) else [np.nan] * 2
            if not (len(have) == 2 and all(abs(float(a) - b) <= 1e-3 for a, b in zip(have, want, strict=True))):
                raise WorkbenchError(
                    f"{where}: measured for another design: its film {name} is {have[0]} x {have[1]} mm, "
                    f"this job's {want[0]} x {want[1]} mm"
                )
    got = (prof.get("material") or {}).get("name")
    if material is not None and got != material:
        raise WorkbenchError(f"{where}: measured for material {got!r}, this job's is {material!r}")

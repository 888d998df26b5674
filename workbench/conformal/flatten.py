"""Conformal map of a disc-shaped mesh onto a rectangle at physical scale."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from workbench.conformal.cetm import (
    DegenerateMetricError,
    Metric,
    NewtonOptions,
    NewtonResult,
    conformal_scale_factors,
)
from workbench.conformal.corners import choose_corners, corner_positions
from workbench.conformal.distortion import flat_to_surface_singular_values
from workbench.conformal.intrinsic import intrinsic_delaunay
from workbench.conformal.layout import flat_layout, rectangle_boundary, signed_areas
from workbench.errors import UsageError, WorkbenchError
from workbench.mesh.validate import check_disc, face_areas

# Faces that collapse in the print get no print; beyond this share of the surface
# area that is a visible hole in the decoration, not a sliver.
MAX_COLLAPSED_AREA = 1e-3


@dataclass(frozen=True)
class ScaleMode:
    """How the conformal map's free scale is fixed.

    Attributes
    ----------
    kind : {'isometric', 'no-shrink', 'width', 'height'}
        ``isometric``: area-weighted mean of log(3D length / flat length) is 0,
        exact for developable surfaces. ``no-shrink``: the flat print is nowhere
        larger than the surface in any direction (film only stretches).
        ``width``/``height``: the rectangle's width or height is ``value_mm``.
    value_mm : float or None
        Size for ``width``/``height``.
    """

    kind: str = "isometric"
    value_mm: float | None = None

    @classmethod
    def parse(cls, text: str) -> ScaleMode:
        """Read ``isometric``, ``no-shrink``, ``width=MM`` or ``height=MM``."""
        if text in ("isometric", "no-shrink"):
            return cls(text)
        key, sep, value = text.partition("=")
        if sep and key in ("width", "height"):
            try:
                mm = float(value)
            except ValueError:
                mm = float("nan")
            if not (np.isfinite(mm) and mm > 0):
                raise UsageError(f"--scale {text}: {key} must be a positive number of mm")
            return cls(key, mm)
        raise UsageError(f"--scale {text!r}: use isometric, no-shrink, width=MM or height=MM")

    def __str__(self) -> str:
        return self.kind if self.value_mm is None else f"{self.kind}={self.value_mm:g}"


@dataclass(frozen=True)
class FlattenOptions:
    """Settings of :func:`flatten`.

    Attributes
    ----------
    corners : tuple of 4 int, or None
        Corner vertices A, B, C, D (counter-clockwise); None chooses them.
    scale : ScaleMode
        How the physical size is fixed.
    newton : NewtonOptions
        Convergence rule of the conformal solve.
    """

    corners: tuple[int, int, int, int] | None = None
    scale: ScaleMode = ScaleMode()
    newton: NewtonOptions = NewtonOptions()


@dataclass
class FlattenResult:
    """A mesh mapped conformally onto a rectangle.

    Attributes
    ----------
    uv : (#V, 2) float
        Flat positions in mm, corner A at the origin, A→B along +x, in the input's
        vertex order.
    corners : (4,) int
        Vertices A, B, C, D.
    corner_rule : str
        ``'given'``, ``'sharpest-turns'`` or ``'bounding-box'``.
    width_mm, height_mm : float
        Rectangle size.
    scale : ScaleMode
        Scale mode applied.
    newton : NewtonResult
        The conformal solve.
    sigma : (#F, 2) float
        Singular values of the flat-to-surface map per face (see
        :func:`flat_to_surface_singular_values`).
    area_3d : (#F,) float
        Surface area of each face, mm².
    flipped_faces : int
        Faces with negative area in the plane.
    collapsed : (#F,) bool
        Faces with (numerically) zero area in the plane: slivers whose vertices land
        on one line. ``sigma`` is NaN there and statistics leave them out.
    intrinsic_flips : int
        Edge flips of the intrinsic Delaunay triangulation the solve used (0 when
        the input triangulation was used as it is).
    rectangle_mismatch : float
        Relative length difference of opposite sides before they are equalised.
    timings_s : dict
        Seconds per stage.
    """

    uv: np.ndarray
    corners: np.ndarray
    corner_rule: str
    width_mm: float
    height_mm: float
    scale: ScaleMode
    newton: NewtonResult
    sigma: np.ndarray
    area_3d: np.ndarray
    flipped_faces: int
    collapsed: np.ndarray
    intrinsic_flips: int
    rectangle_mismatch: float
    timings_s: dict = field(default_factory=dict)

    @property
    def stretch(self) -> np.ndarray:
        """Isotropic film stretch per face, 3D length / flat length = sqrt(σ₁σ₂); (#F,)."""
        return np.sqrt(self.sigma[:, 0] * self.sigma[:, 1])

    @property
    def conformal_distortion(self) -> np.ndarray:
        """``σ₁ / σ₂`` per face, 1 for a perfectly conformal triangle; (#F,)."""
        return self.sigma[:, 0] / self.sigma[:, 1]


def scale_factor(mode: ScaleMode, sigma: np.ndarray, area_3d: np.ndarray, width: float, height: float) -> float:
    """Factor to multiply flat positions by so that the layout meets a scale mode.

    Parameters
    ----------
    mode : ScaleMode
        Requested scale.
    sigma : (#F, 2) float
        Singular values of the current flat-to-surface map.
    area_3d : (#F,) float
        Surface face areas, the weights of the isometric mean.
    width, height : float
        Current rectangle size.

    Returns
    -------
    float
        ``s``; scaling the layout by ``s`` divides every σ by ``s``.
    """
    if mode.kind == "isometric":
        # mean log stretch after scaling, Σ A log(√(σ₁σ₂)/s) / Σ A, is zero for this s
        log_stretch = 0.5 * np.log(sigma[:, 0] * sigma[:, 1])
        return float(np.exp(np.average(log_stretch, weights=area_3d)))
    if mode.kind == "no-shrink":
        return float(sigma[:, 1].min())  # smallest σ₂ becomes exactly 1
    if mode.kind == "width":
        return mode.value_mm / width
    if mode.kind == "height":
        return mode.value_mm / height
    raise UsageError(f"unknown scale mode {mode.kind!r}")


def flatten(
    V: np.ndarray,
    F: np.ndarray,
    options: FlattenOptions = FlattenOptions(),
    name: str = "mesh",
    log: Callable[[str], None] | None = None,
) -> FlattenResult:
    """Map a disc-shaped mesh conformally onto a rectangle at physical scale.

    Target angle sums: 2π inside, π on the boundary, π/2 at the four corners
    (CETM); Newton's method to a max angle residual of ``options.newton.tol_rad``;
    the boundary placed on the rectangle by arc length and the interior by one
    harmonic solve with the flat metric's cotangent weights; then scaled.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions in mm.
    F : (#F, 3) int
        Triangles, counter-clockwise seen from the decorated side.
    options : FlattenOptions
        Corners, scale, convergence.
    name : str
        The mesh's name in error messages.
    log : callable(str), optional
        Receives progress lines.

    Returns
    -------
    FlattenResult

    Raises
    ------
    WorkbenchError
        The mesh is not a clean disc, the corners are invalid, or the solve fails.
    """
    say = log or (lambda _msg: None)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    loop, E, FE = check_disc(V, F, name)
    if options.corners is None:
        corners, rule = choose_corners(V, F, loop)
    else:
        corners, rule = np.asarray(options.corners, dtype=np.int64), "given"
    pos = corner_positions(loop, corners, len(V))
    start = int(np.flatnonzero(loop == corners[0])[0])
    loop = np.roll(loop, -start)
    say(f"corners A,B,C,D = {','.join(map(str, corners.tolist()))} ({rule})")
    timings["check"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    theta = np.full(len(V), 2.0 * np.pi)
    theta[loop] = np.pi
    theta[corners] = 0.5 * np.pi
    # A boundary vertex with one face must open that face to 180°: degenerate on this
    # triangulation whatever the solver does, so go straight to the intrinsic one.
    valence = np.bincount(F.ravel(), minlength=len(V))
    ears = np.setdiff1d(loop[valence[loop] == 1], corners)
    T, flips = F, 0
    metric = Metric.from_mesh(V, F, E, FE)
    newton = None
    if len(ears) == 0:
        try:
            newton = _solve(metric, theta, corners, options, say)
        except DegenerateMetricError as exc:
            say(f"{exc.faces.size} triangles degenerate; retrying on the intrinsic Delaunay triangulation")
    else:
        say(f"{len(ears)} boundary vertices with a single face; using the intrinsic Delaunay triangulation")
    if newton is None:
        L = np.exp(0.5 * metric.lam[metric.FE])
        force = np.isin(F, ears)  # flip the edge facing each single-face boundary vertex
        T, L, flips = intrinsic_delaunay(F, L, force=force)
        say(f"intrinsic Delaunay: {flips} edge flips")
        metric = Metric.from_lengths(T, L, len(V))
        try:
            newton = _solve(metric, theta, corners, options, say)
        except DegenerateMetricError as exc:
            raise WorkbenchError(
                f"{name}: the conformal metric degenerates in {exc.faces.size} triangles even on the intrinsic "
                "Delaunay triangulation: the mesh has slivers a conformal map cannot keep; remesh it "
                "(isotropic remeshing) or choose other corners"
            ) from None
    timings["newton"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    lengths = metric.edge_lengths(newton.u)
    key = np.sort(np.stack([loop, np.roll(loop, -1)], axis=1), axis=1)
    edge_id = np.searchsorted(metric.E[:, 0] * len(V) + metric.E[:, 1], key[:, 0] * len(V) + key[:, 1])
    boundary_xy, width, height, mismatch = rectangle_boundary(lengths[edge_id], pos)
    uv = flat_layout(newton.cot, loop, boundary_xy, newton.assembler, newton.solver)
    timings["layout"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    area_3d = face_areas(V, F)
    # input faces drawn through an intrinsic triangulation can collapse onto a line
    # (a boundary sliver whose three vertices end up on one side of the rectangle)
    flat_area = signed_areas(uv, F)
    flipped = int((flat_area < -1e-9 * area_3d).sum())
    collapsed = np.abs(flat_area) <= 1e-9 * area_3d
    lost = area_3d[collapsed].sum() / area_3d.sum()
    if lost > MAX_COLLAPSED_AREA:
        f = int(np.flatnonzero(collapsed)[np.argmax(area_3d[collapsed])])
        raise WorkbenchError(
            f"{name}: {int(collapsed.sum())} faces ({100 * lost:.2g} % of the surface, largest face {f} with vertices "
            f"{', '.join(map(str, F[f].tolist()))}) collapse onto a line in the print and would get no print; "
            "make the boundary vertex of such a face a corner, or split the face"
        )
    sigma = np.full((len(F), 2), np.nan)
    ok = ~collapsed
    sigma[ok] = flat_to_surface_singular_values(V, F[ok], uv)
    s = scale_factor(options.scale, sigma[ok], area_3d[ok], width, height)
    uv *= s
    sigma /= s
    if flipped:
        say(f"warning: {flipped} faces are flipped in the layout")
    timings["metrics"] = time.perf_counter() - t0
    return FlattenResult(
        uv=uv,
        corners=corners,
        corner_rule=rule,
        width_mm=width * s,
        height_mm=height * s,
        scale=options.scale,
        newton=newton,
        sigma=sigma,
        area_3d=area_3d,
        flipped_faces=flipped,
        collapsed=collapsed,
        intrinsic_flips=flips,
        rectangle_mismatch=mismatch,
        timings_s=timings,
    )


def _solve(metric, theta, corners, options, say):
    return conformal_scale_factors(
        metric,
        theta,
        fixed=int(corners[0]),
        options=options.newton,
        progress=lambda it, res: say(f"Newton step {it}: max angle residual {res:.2e} rad"),
    )

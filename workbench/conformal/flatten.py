"""Conformal map of a disc-shaped mesh onto a rectangle at physical scale."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from workbench.conformal.cetm import (
    DegenerateMetricError,
    NewtonOptions,
    NewtonResult,
    angle_sums,
    conformal_scale_factors,
)
from workbench.conformal.corner_search import boundary_sites, corner_response, even_turning_targets, search_corners
from workbench.conformal.corners import candidate_corners, choose_corners, corner_positions
from workbench.conformal.distortion import flat_to_surface_singular_values, weighted_quantiles
from workbench.conformal.intrinsic import IntrinsicTriangulation
from workbench.conformal.layout import (
    dirichlet_layout,
    flat_layout,
    free_boundary,
    polygon_self_intersections,
    rectangle_boundary,
    signed_areas,
)
from workbench.conformal.overlay import common_subdivision, trace_input_edges
from workbench.errors import UsageError, WorkbenchError
from workbench.mesh.topology import face_components, unique_edges
from workbench.mesh.validate import check_disc, face_areas

# Faces the print crowds below what it can carry get no print of their own; a connected
# region of them beyond this share of the surface area is a visible hole in the
# decoration, not a sliver.
MAX_CROWDED_AREA = 1e-3
# A face is crowded when it prints below what the print can carry and this many times
# smaller than the map's typical scale would print it.
CROWDING = 4.0
# What a print can carry: half a pixel at 300 dpi, mm (design passes its own dpi).
DEFAULT_MIN_PRINT_MM = 0.5 * 25.4 / 300


class CrowdingError(WorkbenchError):
    """The rectangle shrinks part of the surface below what the print can carry.

    Attributes
    ----------
    corners : (4,) int
        The corners used.
    share : float
        Share of the surface area crowded.
    region_vertices : (k,) int
        Input vertices of the largest connected crowded region.
    region_share : float
        Its share of the surface area.
    """

    def __init__(self, message, corners, share, region_vertices, region_share):
        super().__init__(message)
        self.corners, self.share = corners, share
        self.region_vertices, self.region_share = region_vertices, region_share


MIN_SIZE_MM, MAX_SIZE_MM = 0.01, 1e5


@dataclass(frozen=True)
class ScaleMode:
    """How the conformal map's free scale is fixed.

    Attributes
    ----------
    kind : {'isometric', 'area', 'no-shrink', 'width', 'height', 'rim'}
        ``isometric``: area-weighted mean of log(3D length / flat length) is 0,
        exact for developable surfaces. ``area``: the film's area equals the
        surface's (also exact for developable surfaces; on deep parts, where the
        log stretch is skewed, it keeps the print near the part's developed size
        while ``isometric`` can make it many times larger). ``rim`` (free outline only): the film
        keeps the part's rim lengths, as the free outline is solved. ``no-shrink``: the flat print is nowhere
        larger than the surface in any direction (film only stretches).
        ``width``/``height``: the rectangle's width or height is ``value_mm``.
    value_mm : float or None
        Size for ``width``/``height``.
    """

    kind: str = "isometric"
    value_mm: float | None = None

    @classmethod
    def parse(cls, text: str) -> ScaleMode:
        """Read ``isometric``, ``area``, ``no-shrink``, ``rim``, ``width=MM`` or ``height=MM``."""
        if text in ("isometric", "area", "no-shrink", "rim"):
            return cls(text)
        key, sep, value = text.partition("=")
        if sep and key in ("width", "height"):
            try:
                mm = float(value)
            except ValueError:
                mm = float("nan")
            # a film from a hundredth of a millimetre to 100 m: beyond, stretch and print size overflow
            if not (np.isfinite(mm) and MIN_SIZE_MM <= mm <= MAX_SIZE_MM):
                raise UsageError(
                    f"--scale {text}: {key} must be a number of mm from {MIN_SIZE_MM:g} to {MAX_SIZE_MM:g}"
                )
            return cls(key, mm)
        raise UsageError(f"--scale {text!r}: use isometric, area, no-shrink, rim, width=MM or height=MM")

    @classmethod
    def default(cls, outline: str) -> ScaleMode:
        """``isometric`` for a rectangle, ``area`` for a free outline.

        A free outline of a deep part at isometric scale can be many times the part
        (the scanned face: 9.5 times its area, because the rim keeps its length while
        the middle shrinks, and the mean log stretch weighs that heavily); ``area``
        keeps the film as large as the surface it covers.
        """
        return cls("area" if outline == "free" else "isometric")

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
    flips : bool or None
        None: solve on the input triangulation and flip only when it does not
        carry the solution; True: always keep the triangulation Delaunay.
    outline : {'rectangle', 'free'}
        ``rectangle``: corners at π/2, straight sides. ``free``: the conformal map
        with the least area distortion, boundary scale factors 0 (the film keeps
        the rim's lengths, as in Boundary First Flattening, Sawhney and Crane
        2017), interior angle sums 2π, boundary angles free; ``corners`` unused.
    min_print_mm : float
        The smallest printed size (square root of a face's printed area, mm) the
        print can carry; a face that prints smaller, and ``CROWDING`` times smaller
        than the map's typical scale would print it, is crowded. Default half a
        pixel at 300 dpi.
    check_overlap : bool
        Refuse a free outline that overlaps itself (the automatic film split turns
        it off to cut the layout instead).
    corners_from : str or None
        Where the given corners came from, as an error about them names it (the
        option ``--corners``, a job's ``JOB.toml: object.corners``); None: the mesh's
        name and ``corners``.
    """

    corners: tuple[int, int, int, int] | None = None
    scale: ScaleMode = ScaleMode()
    newton: NewtonOptions = NewtonOptions()
    flips: bool | None = None
    min_print_mm: float = DEFAULT_MIN_PRINT_MM
    outline: str = "rectangle"
    check_overlap: bool = True
    corners_from: str | None = None


@dataclass
class FlattenResult:
    """A mesh mapped conformally onto a rectangle.

    When the solve flipped edges, the map of an input triangle is piecewise
    (projective) over the common subdivision of the input and the flat
    triangulation; the result then carries that subdivision as its mesh: the
    input vertices first, in their order, then the points where flat edges cross
    input edges. Otherwise ``V``, ``F`` are the input's.

    Attributes
    ----------
    V : (#Vs, 3) float
        Surface positions in mm of the output mesh's vertices; ``V[:n_input_vertices]``
        are the input's.
    F : (#Fs, 3) int
        Output triangles, counter-clockwise, each inside one input triangle.
    parent : (#Fs,) int
        The input triangle each output triangle lies in.
    n_input_vertices : int
        #V of the input.
    uv : (#Vs, 2) float
        Flat positions in mm, corner A at the origin, A→B along +x.
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
    sigma : (#Fs, 2) float
        Singular values of the flat-to-surface map per output face (see
        :func:`flat_to_surface_singular_values`).
    area_3d : (#Fs,) float
        Surface area of each output face, mm².
    flipped_faces : int
        Output faces with negative area in the plane.
    collapsed : (#Fs,) bool
        Output faces with (numerically) zero area in the plane. ``sigma`` is NaN
        there and statistics leave them out.
    crowded : (#Fs,) bool
        Output faces printed smaller than ``min_print_mm`` (collapsed ones too);
        no connected region of them covers more than ``MAX_CROWDED_AREA`` of the
        surface, or flatten refuses.
    intrinsic_flips : int
        Ptolemy edge flips the solve made.
    rectangle_mismatch : float
        Relative length difference of opposite sides before they are equalised.
    timings_s : dict
        Seconds per stage.
    """

    V: np.ndarray
    F: np.ndarray
    parent: np.ndarray
    n_input_vertices: int
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
    crowded: np.ndarray
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


def scale_factor(
    mode: ScaleMode, sigma: np.ndarray, area_3d: np.ndarray, width: float, height: float, rim_ratio: float = 1.0
) -> float:
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
    rim_ratio : float
        3D rim length / flat rim length, for ``rim``.

    Returns
    -------
    float
        ``s``; scaling the layout by ``s`` divides every σ by ``s``.
    """
    if mode.kind == "isometric":
        # mean log stretch after scaling, Σ A log(√(σ₁σ₂)/s) / Σ A, is zero for this s
        log_stretch = 0.5 * np.log(sigma[:, 0] * sigma[:, 1])
        return float(np.exp(np.average(log_stretch, weights=area_3d)))
    if mode.kind == "area":
        # a face's flat area is A / (σ₁σ₂); after scaling by s it is s² A / (σ₁σ₂), and
        # Σ s² A / (σ₁σ₂) = Σ A gives s
        return float(np.sqrt(area_3d.sum() / (area_3d / (sigma[:, 0] * sigma[:, 1])).sum()))
    if mode.kind == "no-shrink":
        return float(sigma[:, 1].min())  # smallest σ₂ becomes exactly 1
    if mode.kind == "width":
        return mode.value_mm / width
    if mode.kind == "height":
        return mode.value_mm / height
    if mode.kind == "rim":
        return rim_ratio
    raise UsageError(f"unknown scale mode {mode.kind!r}")


def input_log_lengths(V: np.ndarray, F: np.ndarray, name: str = "mesh") -> np.ndarray:
    """Penner coordinates of a mesh, normalised: ``2 log(l / l̄)`` with ``l̄`` the geometric mean length.

    Normalising makes every later number independent of the mesh's unit: the same
    mesh in µm, mm or m gives the same coordinates up to round-off.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions.
    F : (#F, 3) int
        Triangles.
    name : str
        The mesh's name in error messages.

    Returns
    -------
    lam : (#F, 3) float
        For the edge opposite each corner.

    Raises
    ------
    WorkbenchError
        An edge of zero length (two vertices at one position).
    """
    L = np.linalg.norm(V[F[:, [2, 0, 1]]] - V[F[:, [1, 2, 0]]], axis=2)
    zero = np.argwhere(L <= 0)
    if len(zero):
        f, k = (int(i) for i in zero[0])
        a, b = int(F[f, (k + 1) % 3]), int(F[f, (k + 2) % 3])
        raise WorkbenchError(
            f"{name}: {len(zero) // 2 or 1} edges have zero length (vertices {a} and {b} of face {f} are at one "
            "position); merge duplicate vertices"
        )
    with np.errstate(divide="ignore"):
        logL = np.log(L)
    return 2.0 * (logL - logL.mean())


def flatten(
    V: np.ndarray,
    F: np.ndarray,
    options: FlattenOptions = FlattenOptions(),
    name: str = "mesh",
    log: Callable[[str], None] | None = None,
) -> FlattenResult:
    """Map a disc-shaped mesh conformally onto a rectangle at physical scale.

    Target angle sums: 2π inside, π on the boundary, π/2 at the four corners.
    Newton's method with Ptolemy flips that keep the triangulation Delaunay for
    the current metric (:func:`conformal_scale_factors`) to a max angle residual
    of ``options.newton.tol_rad``; the boundary placed on the rectangle by arc
    length and the interior by one harmonic solve with the flat metric's cotangent
    weights; then, when edges were flipped, the common subdivision of input and
    flat triangulation (:mod:`workbench.conformal.overlay`); then scaled.

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
        The mesh is not a clean disc, the corners are invalid, the solve fails, or
        part of the surface would collapse in the print.
    """
    say = log or (lambda _msg: None)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    loop, E, FE = check_disc(V, F, name)
    free = options.outline == "free"
    if options.outline not in ("rectangle", "free"):
        raise UsageError(f"outline {options.outline!r}: use rectangle or free")
    if free:
        if options.corners is not None:
            raise UsageError("corners belong to a rectangle; a free outline has none (leave them out)")
        corners, rule = np.empty(0, dtype=np.int64), "free outline"
    else:
        if options.scale.kind == "rim":
            raise UsageError("scale rim keeps the rim's lengths: it needs outline free")
        if options.corners is None:
            corners, rule = choose_corners(V, F, loop)
        else:
            corners, rule = np.asarray(options.corners, dtype=np.int64), "given"
        try:
            corner_positions(loop, corners, len(V))
        except WorkbenchError as exc:
            where = options.corners_from or f"{name}: corners"
            raise WorkbenchError(f"{where} {','.join(map(str, corners.tolist()))}: {exc}") from None
        start = int(np.flatnonzero(loop == corners[0])[0])
        loop = np.roll(loop, -start)
        say(f"corners A,B,C,D = {','.join(map(str, corners.tolist()))} ({rule})")
    lam = input_log_lengths(V, F, name)
    timings["check"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    n_input, F_input = len(V), F
    splits = 0
    face_origin = np.arange(len(F))  # input face of each face of the (split) mesh
    split_rounds = 0
    while True:
        try:
            newton, tri = _solve(V, F, lam, loop, corners, options, say, (E, FE) if splits == 0 else None)
        except WorkbenchError as exc:
            raise WorkbenchError(f"{name}: {exc}") from None
        if not newton.degenerate.any():
            break
        # Without the double cover of the disc (Campen et al. 2021), boundary edges are
        # never flipped, and a triangle on the boundary can end degenerate (its apex
        # pushed onto the boundary line). Splitting that boundary edge on the input mesh
        # gives the apex room: the surface is unchanged, the new vertex comes after
        # the input's.
        bad = np.flatnonzero(newton.degenerate)
        edges = _boundary_edges_near(tri, bad)
        if split_rounds == MAX_SPLIT_ROUNDS or len(edges) == 0:
            raise WorkbenchError(
                f"{name}: the conformal metric degenerates in {len(bad)} triangles at the boundary even after "
                f"{splits} boundary edge splits (near vertex {int(tri.F[bad[0], 0])}); remesh the boundary"
            )
        V, F, loop, origin = _split_boundary_edges(V, F, loop, edges)
        split_rounds += 1
        face_origin = face_origin[origin]
        splits += len(edges)
        lam = input_log_lengths(V, F, name)
        say(f"{len(bad)} triangles degenerate at the boundary: split {len(edges)} boundary edges and solve again")
    timings["newton"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    u = newton.u
    # boundary edges are never flipped: their Penner coordinates are the input's
    if splits:
        _, FE, _ = unique_edges(F)
    bf, bk = np.nonzero(np.bincount(FE.ravel(), minlength=FE.max() + 1)[FE] == 1)
    src = F[bf, (bk + 1) % 3]
    blen = np.zeros(len(V))
    blen[src] = np.exp(0.5 * (lam[bf, bk] + u[src] + u[F[bf, (bk + 2) % 3]]))
    try:
        if free:
            boundary_xy, mismatch = free_boundary(blen[loop], angle_sums(tri.F, newton.alpha, len(V))[loop])
            X = dirichlet_layout(tri.F, newton.cot, loop, boundary_xy, newton.assembler)
            if options.check_overlap:
                check_outline_simple(V, loop, X[loop])
            X -= X.min(axis=0)
            width, height = (float(x) for x in X.max(axis=0))
        else:
            boundary_xy, width, height, mismatch = rectangle_boundary(
                blen[loop], corner_positions(loop, corners, len(V))
            )
            X = flat_layout(newton.cot, loop, boundary_xy, newton.assembler, newton.solver)
    except WorkbenchError as exc:
        raise WorkbenchError(f"{name}: {exc}") from None
    timings["layout"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    if newton.flips:
        try:
            crossings = trace_input_edges(F, lam, tri, u, len(V))
            V_out, F_out, uv, parent = common_subdivision(V, F, tri.F, X, crossings)
        except WorkbenchError as exc:
            raise WorkbenchError(f"{name}: {exc}") from None
        say(f"common subdivision: {len(crossings['t_in'])} edge crossings, {len(F_out)} triangles")
    else:
        V_out, F_out, uv, parent = V, F, X, np.arange(len(F))
    parent = face_origin[parent]
    timings["overlay"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    area_3d = face_areas(V_out, F_out)
    flat_area = signed_areas(uv, F_out)
    # relative to the face's share of the surface: the map's own area scale is
    # (width·height) / (surface area)
    rel = flat_area / (area_3d * (width * height / area_3d.sum()))
    flipped = int((rel < -1e-9).sum())
    collapsed = np.abs(rel) <= 1e-9
    sigma = np.full((len(F_out), 2), np.nan)
    ok = ~collapsed
    sigma[ok] = flat_to_surface_singular_values(V_out, F_out[ok], uv)
    rim_3d = np.linalg.norm(V[np.roll(loop, -1)] - V[loop], axis=1).sum()
    rim_flat = np.linalg.norm(X[np.roll(loop, -1)] - X[loop], axis=1).sum()
    s = scale_factor(options.scale, sigma[ok], area_3d[ok], width, height, rim_3d / rim_flat)
    uv = uv * s
    sigma /= s
    # crowded: printed smaller than the print can carry, and shrunk at least CROWDING
    # times more than the map's typical (area-weighted median) scale: a tiny face of a
    # fine mesh is not crowded, a face of a protrusion the rectangle squeezes is
    printed = np.sqrt(np.abs(flat_area)) * s
    scale_of_face = printed / np.sqrt(area_3d)
    typical = float(weighted_quantiles(scale_of_face[ok], area_3d[ok], [0.5])[0])
    crowded = collapsed | ((printed < options.min_print_mm) & (scale_of_face * CROWDING < typical))
    share = float(area_3d[crowded].sum() / area_3d.sum())
    if share > MAX_CROWDED_AREA:
        # a region the print cannot carry, not scattered single triangles (the ears of a
        # jagged scan boundary are squeezed locally, whatever the corners)
        err = _crowding_error(name, F_input, F_out, parent, crowded, area_3d, corners, share, options.min_print_mm)
        if err.region_share > MAX_CROWDED_AREA:
            raise err
    if flipped:
        say(f"warning: {flipped} faces are flipped in the layout")
    timings["metrics"] = time.perf_counter() - t0
    return FlattenResult(
        V=V_out,
        F=F_out,
        parent=parent,
        n_input_vertices=n_input,
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
        crowded=crowded,
        intrinsic_flips=newton.flips,
        rectangle_mismatch=mismatch,
        timings_s=timings,
    )


def check_outline_simple(V: np.ndarray, loop: np.ndarray, outline: np.ndarray) -> None:
    """Refuse a free outline that overlaps itself, naming where on the part.

    A free outline is only locally injective: a part that winds around more than a
    full turn (a spiral ramp, a deep C) lays out overlapping itself, and one film
    cannot be printed there.

    Parameters
    ----------
    V : (#V, 3) float
        Surface positions, mm.
    loop : (#B,) int
        Boundary loop, vertex indices.
    outline : (#B, 2) float
        The loop's flat positions.

    Raises
    ------
    WorkbenchError
        One line (the caller adds the mesh's name): the first crossing's two rim vertices and their 3D positions.
    """
    pairs = polygon_self_intersections(outline)
    if len(pairs) == 0:
        return
    i, j = loop[pairs[0, 0]], loop[pairs[0, 1]]

    def at(v):
        return "(" + ", ".join(f"{c:.1f}" for c in V[v]) + ") mm"

    raise WorkbenchError(
        f"the free outline overlaps itself: the rim at vertex {i} {at(i)} crosses the rim at vertex {j} "
        f"{at(j)} in the flat layout ({len(pairs)} crossing rim edge pairs); one film cannot lie there: "
        "use several films or a rectangle"
    )


def _crowding_error(name, F_in, F_out, parent, crowded, area_3d, corners, share, min_print_mm) -> CrowdingError:
    """The refusal, naming the largest connected crowded region."""
    idx = np.flatnonzero(crowded)
    labels = face_components(F_out[idx])
    sizes = np.bincount(labels, area_3d[idx])
    region = idx[labels == np.argmax(sizes)]
    verts = np.unique(F_in[parent[region]])
    region_share = float(area_3d[region].sum() / area_3d.sum())
    shown = ", ".join(map(str, verts[:6].tolist())) + (", ..." if len(verts) > 6 else "")
    what = f"the rectangle with corners {','.join(map(str, corners.tolist()))}" if len(corners) else "the free outline"
    return CrowdingError(
        f"{name}: {what} shrinks {100 * share:.2g} % of "
        f"the surface below {min_print_mm:.3g} mm in the print (largest region: {100 * region_share:.2g} % of the "
        f"surface, {len(verts)} input vertices: {shown})",
        corners,
        share,
        verts,
        region_share,
    )


# Rounds of boundary edge splits before a degenerate boundary triangle is reported.
MAX_SPLIT_ROUNDS = 4


def _solve(V, F, lam, loop, corners, options, say, edges):
    """Conformal scale factors on the input triangulation, else with Ptolemy flips."""
    theta = np.full(len(V), 2.0 * np.pi)
    if options.outline == "free":
        theta[loop] = np.nan  # free boundary angles, boundary scale factors 0
        fixed = loop
    else:
        theta[loop] = np.pi
        theta[corners] = 0.5 * np.pi
        fixed = int(corners[0])
    # The input triangulation first: on a clean mesh it carries the solution and the
    # map stays linear on every input triangle (no subdivision). When it does not
    # (a triangle would degenerate), Ptolemy flips keep the triangulation Delaunay.
    for flip in (True,) if options.flips else (False, True):
        tri = IntrinsicTriangulation.from_mesh(F, lam, len(V), None if edges is None else edges[1], flips=flip)
        try:
            newton = conformal_scale_factors(
                tri,
                theta,
                fixed=fixed,
                options=options.newton,
                progress=lambda it, res: say(f"Newton step {it}: max angle residual {res:.2e} rad"),
                flip=flip,
                edges=edges,
            )
        except DegenerateMetricError as exc:
            say(f"{exc}; solving again with intrinsic Delaunay flips")
            continue
        if newton.flips:
            say(f"{newton.flips} Ptolemy edge flips kept the triangulation Delaunay")
        return newton, tri
    raise AssertionError("unreachable: the flipped solve returns or raises")


def _boundary_edges_near(tri: IntrinsicTriangulation, faces: np.ndarray) -> np.ndarray:
    """Boundary edges (from, to) of the given triangles, else those at their vertices; (k, 2)."""
    bf, bk = np.nonzero(tri.T < 0)
    src, dst = tri.F[bf, (bk + 1) % 3], tri.F[bf, (bk + 2) % 3]
    own = np.isin(bf, faces)
    if not own.any():
        own = np.isin(src, tri.F[faces]) | np.isin(dst, tri.F[faces])
    return np.unique(np.stack([src[own], dst[own]], 1), axis=0)


def _split_boundary_edges(V, F, loop, edges):
    """Split each boundary edge (p, q) at its midpoint; the new vertices go after the others.

    Returns the new ``V``, ``F``, boundary loop, and for each new face the row of the
    old ``F`` it lies in.
    """
    V, F = V.copy(), F.copy()
    extra_faces, origin = [], list(range(len(F)))
    nxt = {int(p): int(q) for p, q in zip(loop, np.roll(loop, -1), strict=True)}
    for p, q in edges.tolist():
        m = len(V)
        V = np.vstack([V, 0.5 * (V[p] + V[q])])
        # the face running p -> q: (p, q, r) becomes (p, m, r) and (m, q, r)
        hit = np.flatnonzero(((F == p) & (np.roll(F, -1, axis=1) == q)).any(axis=1))[0]
        k = int(np.flatnonzero(F[hit] == p)[0])
        r = int(F[hit, (k + 2) % 3])
        F[hit] = (p, m, r)
        extra_faces.append((m, q, r))
        origin.append(int(hit))
        nxt[p], nxt[m] = m, q
    F = np.vstack([F, np.array(extra_faces, dtype=np.int64)])
    start = int(loop[0])
    new_loop, v = [start], nxt[start]
    while v != start:
        new_loop.append(v)
        v = nxt[v]
    return V, F, np.array(new_loop, dtype=np.int64), np.array(origin, dtype=np.int64)


# Candidates the corner search adds where a refused one crowded.
MAX_GUIDED = 8


def corners_flanking(loop: np.ndarray, region: np.ndarray) -> np.ndarray | None:
    """Corners that open a crowded region: two at the ends of its stretch of boundary.

    Parameters
    ----------
    loop : (#B,) int
        Boundary loop, counter-clockwise.
    region : (k,) int
        Vertices of the crowded region.

    Returns
    -------
    (4,) int or None
        A, B at the two ends of the boundary stretch the region covers, C, D
        splitting the rest of the loop into thirds (by vertex count); None when the
        region does not reach the boundary or the stretch is too short.
    """
    nb = len(loop)
    pos = np.sort(np.flatnonzero(np.isin(loop, region)))
    if len(pos) < 2:
        return None
    # the stretch is the loop minus the largest gap between the region's boundary vertices
    gaps = np.diff(np.append(pos, pos[0] + nb))
    g = int(np.argmax(gaps))
    start, end = int(pos[(g + 1) % len(pos)]), int(pos[g])
    rest = (start - end) % nb
    if rest < 3 or (end - start) % nb < 1:
        return None
    c, d = (end + rest // 3) % nb, (end + 2 * rest // 3) % nb
    quad = [start, end, c, d]
    if len(set(quad)) < 4:
        return None
    return loop[np.array(quad)].astype(np.int64)


def area_distortion(result: FlattenResult) -> float:
    """Area-weighted standard deviation of the log area scale, over faces that print; 0 for an isometry."""
    ok = ~result.collapsed
    log_area = np.log(result.sigma[ok, 0] * result.sigma[ok, 1])
    w = result.area_3d[ok]
    mean = np.average(log_area, weights=w)
    return float(np.sqrt(np.average((log_area - mean) ** 2, weights=w)))


def flatten_auto_corners(
    V: np.ndarray,
    F: np.ndarray,
    options: FlattenOptions = FlattenOptions(),
    name: str = "mesh",
    log: Callable[[str], None] | None = None,
    verify: int = 6,
    skip: tuple[np.ndarray, ...] = (),
) -> tuple[FlattenResult, dict]:
    """Flatten with the corners that print every face with the least area distortion.

    One solve of the map whose rim turns evenly gives the first-order response of the
    log scale to a corner at each of :data:`~workbench.conformal.corner_search.SITES`
    boundary sites (:mod:`workbench.conformal.corner_search`). A local search from 24
    quadruples spread along the boundary (8 starting points, first side 15, 25 or 35 %
    of the perimeter) predicts the crowding and area distortion of thousands of
    quadruples; the automatic rule's corners (:func:`choose_corners`) and the
    ``verify`` best predicted ones (2 when even the best crowds more than ten times
    what is allowed) are then flattened in full. Those refused (part of the surface
    would shrink below what the print carries) or with a flipped face are out; of the
    rest the one with the least :func:`area_distortion` wins. When no response can be
    computed (both the evenly turning solve and that of the automatic corners fail),
    the spread quadruples themselves are flattened, with up to 8 guided ones that open
    a crowded region.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions in mm.
    F : (#F, 3) int
        Triangles.
    options : FlattenOptions
        As for :func:`flatten`; ``corners`` is ignored.
    name : str
        The mesh's name in messages.
    log : callable(str), optional
        Receives one line per candidate.
    verify : int
        Predicted quadruples flattened in full.
    skip : tuple of (4,) int
        Corner sets already known to fail (a refusal being explained): not solved again.

    Returns
    -------
    result : FlattenResult
        The winner's.
    search : dict
        ``sites`` (boundary sites compared), ``predicted`` (quadruples predicted),
        ``candidates``: one per quadruple flattened, with ``corners``, ``outcome``
        ('ok', 'refused' or 'flipped'), ``area_distortion`` (None unless ok),
        ``reason``, and ``predicted`` {``crowded_share``, ``area_distortion``} where
        the search proposed it.

    Raises
    ------
    WorkbenchError
        Not a clean disc, or no candidate prints every face.
    """
    say = log or (lambda _m: None)
    options = dataclasses.replace(options, outline="rectangle")  # corners belong to a rectangle
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    loop, E, FE = check_disc(V, F, name)
    first, _ = choose_corners(V, F, loop)
    skipped = {frozenset(np.asarray(c).tolist()) for c in skip}
    search = {"sites": 0, "predicted": 0, "candidates": []}
    proposed = _predicted_corners(V, F, loop, first, E, FE, options, search, verify + len(skipped) + 1, say)
    guided_search = proposed is None
    if guided_search:
        proposed = [(c, None) for c in candidate_corners(V, loop, 8)]
    candidates = [(first, None)] + [(c, p) for c, p in proposed if not _same_corners(c, first)]
    candidates = [(c, p) for c, p in candidates if frozenset(c.tolist()) not in skipped]
    if not guided_search:
        least = min((p["crowded_share"] for _, p in proposed), default=0.0)
        # far beyond printable, the prediction's error does not matter: check two, not all
        candidates = candidates[: (verify if least <= 10 * MAX_CROWDED_AREA else 2) + 1]
    seen = {frozenset(c.tolist()) for c, _ in candidates} | skipped
    best, best_score, guided = None, np.inf, 0
    i = 0
    while i < len(candidates):
        c, prediction = candidates[i]
        i += 1
        opts = dataclasses.replace(options, corners=tuple(int(x) for x in c))
        row = {"corners": [int(x) for x in c], "outcome": "ok", "area_distortion": None, "reason": ""}
        if prediction is not None:
            row["predicted"] = prediction
        try:
            r = flatten(V, F, opts, name)
        except CrowdingError as exc:
            row["outcome"], row["reason"] = "refused", str(exc).removeprefix(f"{name}: ")
            # guided: open the crowded region by putting two corners where it meets the boundary
            flank = corners_flanking(loop, exc.region_vertices) if guided_search else None
            if flank is not None and guided < MAX_GUIDED and frozenset(flank.tolist()) not in seen:
                seen.add(frozenset(flank.tolist()))
                candidates.append((flank, None))
                guided += 1
        except WorkbenchError as exc:
            row["outcome"], row["reason"] = "refused", str(exc).removeprefix(f"{name}: ")
        else:
            if r.flipped_faces:
                row["outcome"], row["reason"] = "flipped", f"{r.flipped_faces} flipped faces"
            else:
                row["area_distortion"] = area_distortion(r)
                if row["area_distortion"] < best_score:
                    best, best_score = r, row["area_distortion"]
        search["candidates"].append(row)
        score = "" if row["area_distortion"] is None else f", area distortion {row['area_distortion']:.3f}"
        say(f"corners {i}/{len(candidates)} {','.join(map(str, row['corners']))}: {row['outcome']}{score}")
    if best is None:
        least = min(
            (row["predicted"]["crowded_share"] for row in search["candidates"] if "predicted" in row), default=None
        )
        predicted = (
            f" (of {search['predicted']} quadruples predicted, the least crowded still crowds "
            f"{100 * least:.2g} % of the surface)"
            if least is not None
            else ""
        )
        raise WorkbenchError(
            f"{name}: none of {len(search['candidates'])} corner choices prints every face onto a rectangle"
            f"{predicted}; the part is too long and thin for one rectangle: split it into several films"
        )
    best.corner_rule = "auto"
    return best, search


def _same_corners(a: np.ndarray, b: np.ndarray) -> bool:
    return frozenset(np.asarray(a).tolist()) == frozenset(np.asarray(b).tolist())


def _predicted_corners(V, F, loop, first, E, FE, options, search, count, say):
    """The search's best quadruples as (corners, prediction) pairs, or None when it cannot run."""
    theta, w = even_turning_targets(V, loop, len(V))
    lam = input_log_lengths(V, F)
    sites = loop[boundary_sites(V, loop)]
    k = len(sites)
    old = np.empty(0, dtype=np.int64)
    try:
        tri = IntrinsicTriangulation.from_mesh(F, lam, len(V), FE, flips=True)
        newton = conformal_scale_factors(tri, theta, fixed=int(loop[0]), options=options.newton, edges=(E, FE))
    except WorkbenchError:
        # the evenly turning map is the accurate base; when its solve fails, the
        # rectangle of the automatic corners serves, its corners' response taken off
        # (less exact next to those corners, where the solved scale is singular)
        old = first
        try:
            newton, _ = _solve(
                V,
                F,
                lam,
                np.roll(loop, -int(np.flatnonzero(loop == first[0])[0])),
                first,
                options,
                lambda _m: None,
                (E, FE),
            )
        except WorkbenchError:
            return None
    # a triangle the solve left degenerate at the rim has an infinite cotangent:
    # weightless here, it barely moves the response of the rest
    cot = np.where(newton.degenerate[:, None] | ~np.isfinite(newton.cot), 0.0, newton.cot)
    try:
        G = corner_response(newton.assembler, cot, np.concatenate([sites, old]), loop, w, len(V))
    except WorkbenchError:
        return None
    base = newton.u[: len(V)] - G[:, k:].sum(axis=1)
    G = G[:, :k]
    starts = [
        np.array([r, r + int(side * k), r + k // 2, r + k // 2 + int(side * k)]) % k
        for side in (0.15, 0.25, 0.35)
        for r in range(0, k // 2, max(1, k // 16))
    ]
    optima, evaluated = search_corners(
        face_areas(V, F), F, base, G, starts, options.min_print_mm, CROWDING, 0.5 * MAX_CROWDED_AREA
    )
    search["sites"], search["predicted"] = k, evaluated
    say(f"predicted {evaluated} corner quadruples on {k} boundary sites from one solve")
    return [
        (sites[q], {"crowded_share": round(share, 6), "area_distortion": round(dist, 6)})
        for q, share, dist in optima[:count]
    ]


def crowding_advice(
    exc: CrowdingError,
    V: np.ndarray,
    F: np.ndarray,
    options: FlattenOptions,
    name: str,
    log: Callable[[str], None] | None = None,
) -> WorkbenchError:
    """The crowding refusal with corners that avoid it, found by :func:`flatten_auto_corners`.

    Parameters
    ----------
    exc : CrowdingError
        The refusal.
    V, F, options, name, log
        As given to :func:`flatten`.

    Returns
    -------
    WorkbenchError
        One line: the refusal, then either the corners to use instead or the
        statement that no rectangle prints this part.
    """
    if options.outline == "free":
        # no corners to move: a free outline that crowds needs the part split into films
        return WorkbenchError(f'{exc}; this part needs several films (a job with films = "auto")')
    say = log or (lambda _m: None)
    say("searching for corners that print every face")
    try:
        best, search = flatten_auto_corners(V, F, options, name, log, skip=(exc.corners,))
    except WorkbenchError:
        return WorkbenchError(
            f"{exc}; none of the corner choices --corners auto compares prints every face: this part needs "
            'another outline or several films (a job with outline = "free" or films = "auto")'
        )
    c = ",".join(map(str, best.corners.tolist()))
    n_ok = sum(row["outcome"] == "ok" for row in search["candidates"])
    return WorkbenchError(
        f"{exc}; corners {c} print every face (best of {n_ok} of {len(search['candidates'])} choices that do): "
        f"use --corners {c}, or --corners auto"
    )

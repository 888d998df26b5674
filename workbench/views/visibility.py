"""Which faces each view sees, and which view owns each face (priority order, no blending)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np

from workbench.camera import Camera
from workbench.raster import _JIT, PARALLEL, depth_buffer

# A point counts as unoccluded when it is no farther than the nearest surface seen
# around it by this share of its depth plus two pixel footprints: the depth buffer
# is exact at pixel centres only, and a point between centres on a steep face sits
# up to a footprint times the slope away from them.
DEPTH_TOLERANCE_REL = 0.005
DEPTH_TOLERANCE_PX = 2.0

if TYPE_CHECKING:
    import scipy.sparse as sp


@numba.njit(**_JIT)
def project_point(cam, X0, X1, X2):
    """Pixel x, y and depth z of a world point for a packed camera (see Camera.packed)."""
    xc = cam[4] * X0 + cam[5] * X1 + cam[6] * X2 + cam[13]
    yc = cam[7] * X0 + cam[8] * X1 + cam[9] * X2 + cam[14]
    zc = cam[10] * X0 + cam[11] * X1 + cam[12] * X2 + cam[15]
    if zc <= 0.0:
        return -1e30, -1e30, zc
    return cam[0] * xc / zc + cam[2], cam[1] * yc / zc + cam[3], zc


@numba.njit(**_JIT)
def unoccluded(depth, width, height, fx, x, y, z):
    """True when a point at pixel (x, y), depth z lies inside the image and in front of
    or on the nearest surface at the surrounding 2x2 pixel centres."""
    if z <= 0.0 or x < -0.5 or y < -0.5 or x > width - 0.5 or y > height - 0.5:
        return False
    j0 = min(max(int(np.floor(x)), 0), width - 1)
    i0 = min(max(int(np.floor(y)), 0), height - 1)
    j1 = min(j0 + 1, width - 1)
    i1 = min(i0 + 1, height - 1)
    d = max(max(depth[i0, j0], depth[i0, j1]), max(depth[i1, j0], depth[i1, j1]))
    return z <= d + DEPTH_TOLERANCE_REL * z + DEPTH_TOLERANCE_PX * z / fx


@numba.njit(parallel=True, **_JIT)
def _unoccluded_many(depth, width, height, fx, xy, z, out):
    for k in numba.prange(len(z)):
        out[k] = unoccluded(depth, width, height, fx, xy[k, 0], xy[k, 1], z[k])


def unoccluded_many(depth, width: int, height: int, fx: float, xy: np.ndarray, z: np.ndarray, out: np.ndarray) -> None:
    """:func:`unoccluded` for points (n, 2) at depths (n,), into ``out`` (n,) bool; one parallel loop at a time."""
    xy, z = np.ascontiguousarray(xy), np.ascontiguousarray(z)
    with PARALLEL:
        _unoccluded_many(depth, width, height, fx, xy, z, out)


@dataclass
class ViewVisibility:
    """What one camera sees of the mesh.

    Attributes
    ----------
    camera : Camera
        The view's camera.
    depth : (H, W) float
        Depth of the nearest surface at each pixel centre, mm (+inf: none).
    face_buffer : (H, W) int32
        Nearest face at each pixel centre (-1: none).
    full : (#F,) bool
        Front-facing faces whose corners and centroid are all unoccluded and inside
        the image: the whole face is seen.
    partial : (#F,) bool
        Front-facing faces seen in part: some samples unoccluded, or the face is
        nearest somewhere in the image. Their pixels are tested one by one.
    decoration : (H, W) bool or None
        The image's pixels that are decoration (its alpha or its mask); None: all of them.
        With it, ``full`` and ``partial`` count only what the view sees through them
        (:func:`restrict_to_decoration`).
    """

    camera: Camera
    depth: np.ndarray
    face_buffer: np.ndarray
    full: np.ndarray
    partial: np.ndarray
    decoration: np.ndarray | None = None


def points_unoccluded(vis: ViewVisibility, X: np.ndarray) -> np.ndarray:
    """Which world points (n, 3) a view sees: inside its image and not hidden; (n,) bool."""
    xy, z = vis.camera.project(X)
    out = np.zeros(len(X), dtype=np.bool_)
    cam = vis.camera
    unoccluded_many(vis.depth, cam.width, cam.height, cam.K[0, 0], xy, z, out)
    return out


def faces_facing(V: np.ndarray, F: np.ndarray, center: np.ndarray) -> np.ndarray:
    """Triangles whose decorated side faces a camera centre.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles, counter-clockwise seen from the decorated side.
    center : (3,) float
        Camera centre, mm.

    Returns
    -------
    (#F,) bool
        True where the camera lies on the decorated side of the triangle's plane (every
        point of a triangle then faces it: the test is the same at any point of the plane).
    """
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    normal = np.cross(b - a, c - a)
    return np.einsum("ij,ij->i", normal, np.asarray(center) - (a + b + c) / 3.0) > 0


# A scan's surface is noisy at the scale of its triangles: a tiny triangle folded over inside a
# surface that faces the camera turns its back to it though the part does not. The part's
# surface there is what its neighbours make: the normal averaged over SURFACE_RINGS rings of
# neighbouring faces (one ring: the faces that share a vertex with it). A real fold keeps its
# back turned: two rings from the crease, every face behind it still faces away.
SURFACE_RINGS = 2


def smoothed_face_normals(V: np.ndarray, F: np.ndarray, rings: int = SURFACE_RINGS) -> np.ndarray:
    """Face normals averaged over ``rings`` rings of neighbouring faces, area-weighted.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles, counter-clockwise seen from the decorated side.
    rings : int
        How many times the normals are carried face to vertex and back (each pass widens the
        average by one ring of faces that share a vertex).

    Returns
    -------
    (#F, 3) float
        Unnormalised: twice the area-weighted mean normal, mm² (only its direction is used).
    """
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    n = np.cross(b - a, c - a)  # |n| = twice the face's area: the sums below are area-weighted
    for _ in range(rings):
        # faces to vertices (the sum over the faces around each vertex), then back (the mean of
        # the face's three vertices)
        idx = F.ravel()
        vn = np.stack([np.bincount(idx, np.repeat(n[:, d], 3), minlength=len(V)) for d in range(3)], axis=1)
        n = (vn[F[:, 0]] + vn[F[:, 1]] + vn[F[:, 2]]) / 3.0
    return n


def surface_faces_facing(V: np.ndarray, F: np.ndarray, center: np.ndarray, rings: int = SURFACE_RINGS) -> np.ndarray:
    """Triangles on a part of the surface that faces a camera centre (see SURFACE_RINGS).

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles, counter-clockwise seen from the decorated side.
    center : (3,) float
        Camera centre, mm.
    rings : int
        Rings of neighbouring faces the surface's normal is averaged over.

    Returns
    -------
    (#F,) bool
        True where the camera lies on the decorated side of the triangle's own plane or of the
        surface its neighbours make there.
    """
    to_cam = np.asarray(center) - V[F].mean(axis=1)
    return faces_facing(V, F, center) | (np.einsum("ij,ij->i", smoothed_face_normals(V, F, rings), to_cam) > 0)


def view_visibility(V: np.ndarray, F: np.ndarray, camera: Camera, faces: np.ndarray | None = None) -> ViewVisibility:
    """Depth buffer of a view and the faces it sees fully or in part.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles, counter-clockwise seen from the decorated side.
    camera : Camera
        The view.
    faces : (k,) int, optional
        Test only these faces (every face still occludes); the others are reported
        unseen. The same answer for them as without it, in a fraction of the time when
        only a few faces can matter (suggest-views: those no earlier view sees whole).

    Returns
    -------
    ViewVisibility
    """
    xy, z = camera.project(V)
    face_buffer, depth = depth_buffer(xy, z, F, camera.width, camera.height)
    vis = ViewVisibility(camera, depth, face_buffer, np.zeros(len(F), bool), np.zeros(len(F), bool))
    sub = F if faces is None else F[faces]
    a, b, c = V[sub[:, 0]], V[sub[:, 1]], V[sub[:, 2]]
    centroid = (a + b + c) / 3.0
    front = faces_facing(V, sub, camera.center)
    samples = np.stack([a, b, c, centroid], axis=1).reshape(-1, 3)
    seen = points_unoccluded(vis, samples).reshape(-1, 4)
    in_buffer = np.zeros(len(F), dtype=bool)
    in_buffer[face_buffer[face_buffer >= 0]] = True
    if faces is not None:
        in_buffer = in_buffer[faces]
    full = front & seen.all(axis=1)
    partial = front & ~full & (seen.any(axis=1) | in_buffer)
    if faces is None:
        vis.full, vis.partial = full, partial
    else:
        vis.full[faces], vis.partial[faces] = full, partial
    return vis


def restrict_to_decoration(vis: ViewVisibility, V: np.ndarray, F: np.ndarray, decoration: np.ndarray) -> None:
    """Make a view see only through its decoration pixels (in place).

    A face whose projection's pixels are all decoration stays as it was; one whose pixels
    are all transparent is no longer seen; one with both is seen in part, so that the print
    tests its pixels one by one (:func:`workbench.texture.synthesis.synthesize_print` looks up
    the pixel nearest each surface point). A face's pixels are taken over its projected
    bounding box grown by one pixel: a face decided whole is decoration wherever its points
    land, and a face in doubt is only tested finer.

    Parameters
    ----------
    vis : ViewVisibility
        The view (``full``, ``partial`` and ``decoration`` are replaced).
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles.
    decoration : (H, W) bool
        The view image's decoration pixels (the camera's image size).
    """
    cam = vis.camera
    h, w = decoration.shape
    xy, _ = cam.project(V)
    xs, ys = xy[F, 0], xy[F, 1]  # (#F, 3) px, pixel centres at whole numbers
    # the nearest pixel of a point at x is floor(x + 0.5): the box of those, one pixel wider
    x0 = np.clip(np.floor(xs.min(axis=1) + 0.5) - 1, 0, w - 1).astype(np.int64)
    x1 = np.clip(np.floor(xs.max(axis=1) + 0.5) + 1, 0, w - 1).astype(np.int64)
    y0 = np.clip(np.floor(ys.min(axis=1) + 0.5) - 1, 0, h - 1).astype(np.int64)
    y1 = np.clip(np.floor(ys.max(axis=1) + 0.5) + 1, 0, h - 1).astype(np.int64)
    # decoration pixels in each box from the summed-area table: O(1) per face at any size
    S = np.zeros((h + 1, w + 1), np.int64)
    S[1:, 1:] = decoration.astype(np.int64).cumsum(axis=0).cumsum(axis=1)
    inside = S[y1 + 1, x1 + 1] - S[y0, x1 + 1] - S[y1 + 1, x0] + S[y0, x0]
    every = inside == (y1 - y0 + 1) * (x1 - x0 + 1)
    seen = vis.full | vis.partial
    vis.partial = seen & (inside > 0) & ~(vis.full & every)
    vis.full = vis.full & every
    vis.decoration = decoration


def region_drops(visibilities: list[ViewVisibility], status: np.ndarray, face_area: np.ndarray) -> np.ndarray:
    """What each view could claim and what its region rule left of it (:func:`assign_views`).

    Parameters
    ----------
    visibilities : list of ViewVisibility
        In priority order.
    status : (#F, #views) int8
        Their ownership (:func:`assign_views`).
    face_area : (#F,) float
        Surface area per face, mm².

    Returns
    -------
    (#views, 2) float
        Per view, mm²: the faces it could claim (it sees them, in part or whole, and no
        earlier view claims them whole), and those of them its region rule dropped.
    """
    out = np.zeros((len(visibilities), 2))
    taken = np.zeros(len(face_area), dtype=bool)
    for v, vis in enumerate(visibilities):
        could = (vis.full | vis.partial) & ~taken
        out[v] = face_area[could].sum(), face_area[could & (status[:, v] == 0)].sum()
        taken |= status[:, v] == 1
    return out


def face_adjacency(FE: np.ndarray) -> sp.csr_matrix:
    """Faces sharing an edge; (#F, #F) sparse bool, from ``FE`` (#F, 3) of unique_edges."""
    # SciPy here, not at the top: validate needs this module's visibility kernel only, and
    # importing scipy.sparse took a quarter of its start-up
    import scipy.sparse as sp

    nF = len(FE)
    inc = sp.csr_matrix((np.ones(3 * nF), (np.repeat(np.arange(nF), 3), FE.ravel())))
    A = (inc @ inc.T).tocsr()
    A.setdiag(0)
    A.eliminate_zeros()
    return A


def assign_views(
    visibilities: list[ViewVisibility], regions: list[str], adjacency: sp.csr_matrix, face_area: np.ndarray
) -> np.ndarray:
    """Ownership of faces by views in priority order (paper §3.1).

    A view may claim the faces it sees that no earlier view sees whole; it keeps one
    connected region of them (the largest by surface area, or all with ``'all'``).
    Faces an earlier view sees only in part stay claimable, so the later view fills
    what the earlier one cannot see, pixel by pixel.

    Parameters
    ----------
    visibilities : list of ViewVisibility
        In priority order.
    regions : list of {'largest', 'all'}
        Region rule per view.
    adjacency : (#F, #F) sparse
        Face adjacency (:func:`face_adjacency`).
    face_area : (#F,) float
        Surface area per face, mm².

    Returns
    -------
    status : (#F, #views) int8
        0: the view does not claim the face; 1: it claims the whole face; 2: it
        claims the face where it sees it (per-pixel test).
    """
    nF = len(face_area)
    status = np.zeros((nF, len(visibilities)), dtype=np.int8)
    taken = np.zeros(nF, dtype=bool)
    for v, (vis, rule) in enumerate(zip(visibilities, regions, strict=True)):
        status[:, v] = claim_faces(vis, rule, taken, adjacency, face_area)
        taken |= status[:, v] == 1
    return status


def claim_faces(
    vis: ViewVisibility, rule: str, taken: np.ndarray, adjacency: sp.csr_matrix, face_area: np.ndarray
) -> np.ndarray:
    """What one view claims after the views before it (one step of :func:`assign_views`).

    Parameters
    ----------
    vis : ViewVisibility
        The view.
    rule : {'largest', 'all'}
        Its region rule.
    taken : (#F,) bool
        Faces an earlier view claims and sees whole.
    adjacency : (#F, #F) sparse
        Face adjacency (:func:`face_adjacency`).
    face_area : (#F,) float
        Surface area per face, mm².

    Returns
    -------
    (#F,) int8
        0: not claimed; 1: claimed whole; 2: claimed where the view sees it.
    """
    from scipy.sparse.csgraph import connected_components

    out = np.zeros(len(face_area), dtype=np.int8)
    idx = np.flatnonzero((vis.full | vis.partial) & ~taken)
    if len(idx) == 0:
        return out
    if rule == "largest":
        _, label = connected_components(adjacency[idx][:, idx], directed=False)
        area = np.bincount(label, weights=face_area[idx])
        # ties go to the lowest label, i.e. the component of the lowest face index
        idx = idx[label == int(np.argmax(area))]
    out[idx] = np.where(vis.full[idx], 1, 2)
    return out

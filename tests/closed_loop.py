"""An independent renderer and a misregistration measure, for closed-loop tests of design.

The renderer casts one ray per view pixel centre (trimesh with Embree), interpolates the
hit's texture coordinates barycentrically and samples the print: nothing is shared with
the synthesis, which goes the other way (print pixel → surface → view).
"""

from __future__ import annotations

import cv2
import numpy as np
import trimesh

from workbench.camera import Camera
from workbench.design import read_image
from workbench.validate.score import MARGIN, register_tile


def render_decorated(V, F, vt, rgb, camera: Camera):
    """Image of the decorated mesh seen by ``camera``.

    Returns
    -------
    image : (H, W, 3) uint8
        Rendered print where a ray hits, 0 elsewhere.
    hit_uv_px : (H, W, 2) float
        Print pixel coordinates of each hit (NaN: no hit).
    """
    W, H = camera.width, camera.height
    jj, ii = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    pix = np.stack([jj.ravel(), ii.ravel(), np.ones(W * H)], axis=1)
    d = pix @ np.linalg.inv(camera.K).T @ camera.R  # camera rays to world: Rᵀ K⁻¹ [x y 1]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(camera.center, d.shape)
    mesh = trimesh.Trimesh(V, F, process=False)
    loc, ray, tri = mesh.ray.intersects_location(o, d, multiple_hits=False)
    bary = trimesh.triangles.points_to_barycentric(mesh.triangles[tri], loc)
    uv = np.einsum("ij,ijk->ik", bary, vt[F[tri]])
    rows, cols = rgb.shape[:2]
    px = np.full((H * W, 2), np.nan)
    px[ray, 0] = uv[:, 0] * cols - 0.5
    px[ray, 1] = (1.0 - uv[:, 1]) * rows - 0.5
    px = px.reshape(H, W, 2)
    mapx = np.nan_to_num(px[..., 0], nan=-1e4).astype(np.float32)
    mapy = np.nan_to_num(px[..., 1], nan=-1e4).astype(np.float32)
    img = cv2.remap(rgb, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return img, px


def tile_misregistration(reference, image, mask, tile=64, min_texture=50.0):
    """Translation between two images on square tiles, where it is well defined.

    Each tile is registered as ``workbench validate`` does (normalised correlation, then
    Lucas-Kanade; OpenCV's ECC on same-size tiles is biased towards zero shift).

    Tiles must lie wholly inside ``mask`` and carry gradients in two directions (the
    smaller eigenvalue of the structure tensor per pixel above ``min_texture``): a tile
    with a single straight edge only fixes the shift across it (aperture problem).

    Returns
    -------
    shifts : (n, 2) float
        Per tile, the (dx, dy) with ``image(x + d) ≈ reference(x)``: how far, in pixels,
        the image's content is displaced from the reference's.
    """
    # both smoothed alike (as validate does): a sharp image against a softer one is then
    # registered without bias
    ref = cv2.GaussianBlur(cv2.cvtColor(reference, cv2.COLOR_RGB2GRAY).astype(np.float32), (0, 0), 1.0)
    img = cv2.GaussianBlur(cv2.cvtColor(image, cv2.COLOR_RGB2GRAY).astype(np.float32), (0, 0), 1.0)
    gx = cv2.Sobel(ref, cv2.CV_32F, 1, 0, ksize=3) / 8
    gy = cv2.Sobel(ref, cv2.CV_32F, 0, 1, ksize=3) / 8
    shifts = []
    H, W = ref.shape
    for y in range(0, H - tile + 1, tile):
        for x in range(0, W - tile + 1, tile):
            if not mask[y : y + tile, x : x + tile].all():
                continue
            a = gx[y : y + tile, x : x + tile]
            b = gy[y : y + tile, x : x + tile]
            S = np.array([[(a * a).mean(), (a * b).mean()], [(a * b).mean(), (b * b).mean()]])
            if np.linalg.eigvalsh(S)[0] < min_texture:
                continue
            if y < MARGIN or x < MARGIN or y + tile + MARGIN > H or x + tile + MARGIN > W:
                continue
            d, cc, _ = register_tile(ref[y : y + tile, x : x + tile], img, x, y)
            if d is not None and cc > 0.9:
                shifts.append(d)
    return np.array(shifts).reshape(-1, 2)


def first_hit_depth(V, F, camera: Camera) -> np.ndarray:
    """Distance (mm) from ``camera`` to the first surface each view pixel's ray meets; (H, W), inf: none."""
    W, H = camera.width, camera.height
    jj, ii = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    pix = np.stack([jj.ravel(), ii.ravel(), np.ones(W * H)], axis=1)
    d = pix @ np.linalg.inv(camera.K).T @ camera.R
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(camera.center, d.shape)
    loc, ray, _ = trimesh.Trimesh(V, F, process=False).ray.intersects_location(o, d, multiple_hits=False)
    depth = np.full(H * W, np.inf)
    depth[ray] = np.linalg.norm(loc - camera.center, axis=1)
    return depth.reshape(H, W)


def hidden_by_part(r, v, part) -> np.ndarray:
    """View v's pixels where the whole part lies in front of the design's (decorated) surface.

    The design of a closed part is the surface cut out of it; wherever view v sees that surface
    through the rest of the part (a wall the cut left out), the decorated surface alone would
    show ink the part hides. Returns (H, W) bool.
    """
    cam = r.cameras[v]
    # nearer by more than a micrometre: the cut surface lies on the part's own faces (split at
    # their midpoints, the same plane), so equal depths are the same surface
    return first_hit_depth(*part, cam) < first_hit_depth(r.V, r.F, cam) - 1e-3


def view_check(job, r, vt, v, shift_vt=(0.0, 0.0), part=None):
    """Misregistration (px) of the rendered design against view v's image, and coverage.

    Parameters
    ----------
    job, r, vt
        The job, its :class:`workbench.design.DesignResult` and the design's texture coordinates.
    v : int
        The view.
    shift_vt : (2,) float
        Added to the texture coordinates (the measure must see a moved print).
    part : (V, F), optional
        The whole part, for a closed part whose design is only the surface cut out of it: the
        rest of the part is rendered undecorated, so a decorated pixel behind it (the cut surface
        seen through a wall it does not hold) is hidden, not compared.

    Returns
    -------
    mis : (n,) float
        Per registered tile, the length of its shift, view pixels.
    coverage : float
        Share of the pixels showing faces this view alone claims that the print gives to it.
    """
    cam = r.cameras[v]
    img, px = render_decorated(r.V, r.F, vt + np.asarray(shift_vt), r.rgb, cam)
    if part is not None:
        hidden = hidden_by_part(r, v, part)
        px[hidden] = np.nan
        img[hidden] = 0
    ref = read_image(job.views[v].image, "view")
    rows, cols = r.grid.shape
    hit = np.isfinite(px[..., 0])
    pi = np.clip(np.round(np.nan_to_num(px[..., 1])), 0, rows - 1).astype(int)
    pj = np.clip(np.round(np.nan_to_num(px[..., 0])), 0, cols - 1).astype(int)
    own = hit & (r.owner[pi, pj] == v)
    # faces that are this view's alone (no earlier view claims any part of them),
    # seen through the independent ray cast: the print must give them to this view
    # (with several films the depth buffers are of the input mesh, the design's mesh is the atlas)
    fb, status = r.visibilities[v].face_buffer, r.view_status
    alone = np.zeros(hit.shape, bool)
    earlier = (status[:, :v] != 0).any(axis=1)
    alone[fb >= 0] = (status[fb[fb >= 0], v] != 0) & ~earlier[fb[fb >= 0]]
    coverage = (own & alone).sum() / max(alone.sum(), 1)
    mask = cv2.erode(own.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    shifts = tile_misregistration(ref, img, mask)
    return np.linalg.norm(shifts, axis=1), coverage

"""The job's views on the part: their images and decoration masks, their cameras, what each owns."""

from __future__ import annotations

import numpy as np

from workbench.design_dir import read_image_alpha, read_mask
from workbench.errors import WorkbenchError
from workbench.job import Job
from workbench.mesh.topology import unique_edges
from workbench.mesh.validate import face_areas
from workbench.views.visibility import (
    ViewVisibility,
    assign_views,
    face_adjacency,
    region_drops,
    restrict_to_decoration,
    view_visibility,
)


def assign_job_views(job: Job, V: np.ndarray, F: np.ndarray, images: list[np.ndarray], decorations: list | None = None):
    """Cameras, depth buffers and face ownership of the job's views on a mesh.

    Parameters
    ----------
    job : Job
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        Triangles.
    images : list of (H, W, 3) uint8
        The view images (their sizes are the cameras' sensors).
    decorations : list of (H, W) bool or None, optional
        Per view, its decoration pixels (:func:`read_view_images`); None: every pixel.

    Returns
    -------
    cameras : list of Camera
    visibilities : list of ViewVisibility
    status : (#F, #views) int8
        See :func:`workbench.views.visibility.assign_views`.

    Raises
    ------
    WorkbenchError
        A camera with part of the object behind it, or a view that sees nothing.
    """
    cameras, visibilities = [], []
    for i, (spec, img) in enumerate(zip(job.views, images, strict=True)):
        if spec.size_px is not None and spec.size_px != (img.shape[1], img.shape[0]):
            raise WorkbenchError(
                f"{job.path}: views[{i}].width_px, height_px: {spec.size_px[0]} x {spec.size_px[1]}, but the image "
                f"{spec.image.name} is {img.shape[1]} x {img.shape[0]} px (the view was planned for that size)"
            )
        cam = spec.make_camera(img.shape[1], img.shape[0])
        xy, z = cam.project(V)
        behind = np.flatnonzero(z <= 1e-6 * np.abs(z).max())
        if len(behind):
            where = (np.round(cam.center, 2) + 0.0).tolist()  # + 0.0: print -0.0 as 0.0
            raise WorkbenchError(
                f"{job.path}: views[{i}] ({spec.name!r}): the camera at {where} mm has part "
                f"of the object level with or behind it (vertex {int(behind[0])}); a view camera must see the whole "
                "object in front of it, not from inside or among it"
            )
        cameras.append(cam)
        visibilities.append(view_visibility(V, F, cam))
        if decorations is not None and decorations[i] is not None:
            restrict_to_decoration(visibilities[-1], V, F, decorations[i])
    E, FE, _ = unique_edges(F)
    area = face_areas(V, F)
    status = assign_views(visibilities, [v.region for v in job.views], face_adjacency(FE), area)
    for i, spec in enumerate(job.views):
        if not status[:, i].any():
            seen = int((visibilities[i].full | visibilities[i].partial).sum())
            why = "it sees no front face of the object" if seen == 0 else "earlier views own everything it sees"
            raise WorkbenchError(
                f"{job.path}: views[{i}] ({spec.name!r}) sees nothing of the object to decorate: {why}"
            )
    return cameras, visibilities, status


def read_view_images(job: Job) -> tuple[list[np.ndarray], list[np.ndarray | None]]:
    """The job's view images and, per view, the pixels that are decoration.

    A view decorates with the pixels its ``mask`` marks (nonzero), else with those its image's
    alpha channel leaves visible (alpha above 0), else with all of them. An image with
    transparent pixels and a mask as well is refused: two answers to one question.

    Parameters
    ----------
    job : Job

    Returns
    -------
    images : list of (H, W, 3) uint8
        RGB, an alpha channel laid over the print's background (:func:`read_image`).
    decorations : list of (H, W) bool or None
        Per view, its decoration pixels; None where every pixel is (the view as without a mask).

    Raises
    ------
    WorkbenchError
        One line naming the key: an unreadable image or mask, a mask of another size than its
        image, a mask with an image that has transparent pixels, a view with no decoration pixel.
    """
    images, decorations = [], []
    for i, v in enumerate(job.views):
        where = f"{job.path}: views[{i}]"
        rgb, opaque = read_image_alpha(v.image, f"{where}.image", job.print.background)
        h, w = rgb.shape[:2]
        if v.mask is not None:
            if opaque is not None and not opaque.all():
                raise WorkbenchError(
                    f"{where}.mask: the image {v.image.name} has transparent pixels of its own "
                    f"({int((~opaque).sum())}): its alpha channel or the mask says what is decoration, not both"
                )
            decoration, key, source = read_mask(v.mask, f"{where}.mask", (w, h), v.image.name), "mask", v.mask.name
        else:
            decoration, key, source = opaque, "image", f"{v.image.name}'s alpha channel"
        if decoration is not None and not decoration.any():
            raise WorkbenchError(f"{where}.{key}: {source} marks no pixel as decoration: the view would print nothing")
        images.append(rgb)
        # every pixel decoration: the view exactly as without a mask (same faces, same print)
        decorations.append(None if decoration is None or decoration.all() else decoration)
    return images, decorations


# a region rule that drops more than this share of what the view could claim is said
MAX_REGION_DROP = 0.05


def region_warnings(
    job: Job, visibilities: list[ViewVisibility], status: np.ndarray, face_area: np.ndarray
) -> list[str]:
    """A warning per view whose ``region = "largest"`` dropped more than MAX_REGION_DROP of what it could claim.

    Parameters
    ----------
    job : Job
    visibilities : list of ViewVisibility
        The views' (:func:`assign_job_views`).
    status : (#F, #views) int8
        Their ownership.
    face_area : (#F,) float
        Surface area per face, mm².

    Returns
    -------
    list of str
        One sentence each, naming the view, the share and area dropped, and ``region = "all"``.
    """
    out = []
    for i, (spec, (could, dropped)) in enumerate(
        zip(job.views, region_drops(visibilities, status, face_area), strict=True)
    ):
        if spec.region == "largest" and could > 0 and dropped > MAX_REGION_DROP * could:
            out.append(
                f"view {spec.name!r} (views[{i}]) keeps its largest connected region and drops "
                f"{100 * dropped / could:.1f} % of the surface it could claim"
                f' ({dropped:.0f} of {could:.0f} mm²): region = "all" keeps every region'
            )
    return out

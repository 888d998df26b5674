"""The surface printed of a closed part: what the views see, grown by a margin, cut out into a disc."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from workbench.camera import Camera
from workbench.errors import WorkbenchError
from workbench.figures import surface_figure
from workbench.films.regions import submesh
from workbench.job import Job
from workbench.job_views import assign_job_views
from workbench.mesh import cut as surface_cut
from workbench.mesh.cut import path_length, split_along
from workbench.mesh.io import MeshName
from workbench.mesh.refine import subdivide_to_edge
from workbench.mesh.selection import (
    CLASS_WORDS,
    SEEN,
    SelectionOptions,
    edge_faces,
    face_components,
    read_face_list,
    select_surface,
)
from workbench.mesh.topology import boundary_loops, half_edges, unique_edges
from workbench.mesh.validate import face_areas
from workbench.views.visibility import ViewVisibility

# a closed part's faces are split to edges of at most its diagonal over this (decorated_surface)
REFINE_DIAGONAL = 50


def surface_mode(job: Job, F: np.ndarray) -> str | Path:
    """What the job prints of its mesh: "whole", "seen" or a faces file (the default: "seen" when closed)."""
    if job.object.surface is not None:
        return job.object.surface
    _, _, count = unique_edges(F)
    return "whole" if (count == 1).any() else "seen"


def face_seen(V: np.ndarray, F: np.ndarray, cameras: list[Camera], visibilities: list[ViewVisibility]) -> np.ndarray:
    """How squarely the views see each face: the largest cosine between its normal and a camera that sees it.

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        Triangles.
    cameras : list of Camera
    visibilities : list of ViewVisibility
        The views' (:func:`workbench.views.visibility.view_visibility`).

    Returns
    -------
    (#F,) float
        0 (no view sees it, or only edge-on) to 1 (a view looks straight at it).
    """
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    centroid = V[F].mean(axis=1)
    out = np.zeros(len(F))
    for cam, vis in zip(cameras, visibilities, strict=True):
        d = cam.center - centroid
        cos = np.einsum("ij,ij->i", n, d) / np.maximum(np.linalg.norm(d, axis=1), 1e-300)
        out = np.maximum(out, np.where(vis.full | vis.partial, np.clip(cos, 0.0, 1.0), 0.0))
    return out


def decorated_surface(
    job: Job, V: np.ndarray, F: np.ndarray, images: list[np.ndarray], say, decorations: list | None = None
) -> tuple:
    """The surface to print, cut out of the mesh into a disc: what the views see, or the job's faces.

    "seen": every face a view sees (in whole or in part), grown by the margin
    (``[object] surface_margin_mm``, default the print's bleed: the film is made to reach as
    far past what the views see as the print reaches past its outline), holes of at most
    :data:`workbench.mesh.selection.SMALL_SHARE` of it filled, the largest piece kept
    (:func:`workbench.mesh.selection.select_surface`). A faces file is taken as it is, and
    must be one piece. Then the selection is cut out and, when it is no disc, cut along the
    cheapest seams (:func:`workbench.mesh.cut.cut_to_disc`), priced by how squarely the views
    see each face.

    The faces kept are every face some view sees, so the views' depth buffers on the cut
    surface are those on the whole part: what is left out is hidden or faces away, and (on a
    closed solid, whose first surface along any ray faces the camera) hides nothing.

    Parameters
    ----------
    job : Job
    V : (#V, 3) float
        The mesh, mm.
    F : (#F, 3) int
        Its triangles.
    images : list of (H, W, 3) uint8
        The view images.
    say : callable(str)
        Progress lines.
    decorations : list of (H, W) bool or None, optional
        Per view, its decoration pixels (:func:`read_view_images`): a view sees only through them.

    Returns
    -------
    Vd : (#Vd, 3) float
        The disc's vertices, mm: the selected vertices in the mesh's order, then those
        repeated along the seams.
    Fd : (#Fd, 3) int
        Its triangles: the selected faces in the mesh's order.
    report : dict
        design.json's ``surface`` (and ``warnings`` and ``picture``, ``surface.png``'s bytes,
        popped by the caller).

    Raises
    ------
    WorkbenchError
        A non-manifold or inconsistently oriented mesh, a bad faces file, a faces file of
        several pieces, a selection that cannot be cut into a disc.
    """
    name = job.object.mesh
    mode = surface_mode(job, F)
    where = f"{job.path}: object.surface"
    if isinstance(job.object.corners, tuple):
        raise WorkbenchError(
            f"{job.path}: object.corners: corner vertices are the mesh's, but the surface printed is cut out of "
            f"{'the closed mesh' if job.object.surface is None else 'it'} and numbered anew: "
            'use corners = "auto" or leave them out'
        )
    if isinstance(job.films, tuple):
        for i, spec in enumerate(job.films):
            if spec.faces is not None:
                raise WorkbenchError(
                    f"{job.path}: films[{i}].faces: face indices of the mesh, but the film's surface is cut out "
                    "of it (a closed mesh, or [object] surface): give the film as views = [...]"
                )
    bad = np.flatnonzero(~np.isfinite(V).all(axis=1))
    if len(bad):
        raise WorkbenchError(f"{name}: {len(bad)} vertices have NaN or infinite coordinates (vertex {int(bad[0])})")
    repeated = np.flatnonzero((F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0]))
    if len(repeated):
        raise WorkbenchError(f"{name}: {len(repeated)} faces repeat a vertex ({MeshName(name).faces(repeated)})")
    margin = job.print.bleed_mm if job.object.surface_margin_mm is None else job.object.surface_margin_mm
    refined = None
    if not isinstance(mode, Path):
        # the surface is chosen in whole faces and its margin measured along edges, but a CAD
        # export spans a flat side with two triangles (a 12-triangle box left a rim of 3
        # vertices): its faces are split until no edge exceeds the margin (the film's rim then
        # lies from the margin to twice it beyond what the views see) nor 1 / REFINE_DIAGONAL of
        # the part's diagonal (the map's sampling of a flat side: a box of 100 x 60 x 30 mm in
        # 12 triangles becomes 25k, its 5 mm grid of 2,496 triangles 34k); a scan's fine faces
        # stay as they are
        diagonal = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
        max_edge = min(margin if margin > 0 else np.inf, diagonal / REFINE_DIAGONAL)
        n0 = len(F)
        V, F = subdivide_to_edge(V, F, max_edge)
        if len(F) != n0:
            refined = {"faces_before": n0, "faces_after": len(F), "max_edge_mm": round(max_edge, 4)}
            say(f"{name.name}: faces split to edges of at most {max_edge:.2f} mm: {n0} -> {len(F)} faces")
    E, FE, count = unique_edges(F)
    if (count > 2).any():
        e = E[np.argmax(count > 2)]
        raise WorkbenchError(f"{name}: edge ({e[0]}, {e[1]}) is shared by {int(count.max())} faces: not a manifold")
    ef = edge_faces(F, FE, len(E))
    H = half_edges(F).reshape(-1, 2)  # as FE: the edge opposite each corner, as its face runs it
    direction = np.where(H[:, 0] < H[:, 1], 1.0, -1.0)
    twisted = np.flatnonzero(np.abs(np.bincount(FE.ravel(), weights=direction, minlength=len(E))) > 1)
    if len(twisted):
        e = E[twisted[0]]
        raise WorkbenchError(
            f"{name}: faces are inconsistently oriented (both faces of edge ({e[0]}, {e[1]}) run it the same way)"
        )
    cameras, visibilities, _ = assign_job_views(job, V, F, images, decorations)
    seen_cos = face_seen(V, F, cameras, visibilities)
    seen = np.zeros(len(F), bool)
    for vis in visibilities:
        seen |= vis.full | vis.partial
    if isinstance(mode, Path):
        wanted = np.zeros(len(F), bool)
        wanted[read_face_list(mode, len(F), where)] = True
        pieces = int(face_components(ef, wanted).max()) + 1
        if pieces > 1:
            raise WorkbenchError(f"{where}: {mode}: the faces form {pieces} pieces (joined by edges); a film is one")
        region, sel = select_surface(V, F, E, ef, wanted, SelectionOptions(0.0, 0.0), seen_cos)
    else:
        region, sel = select_surface(V, F, E, ef, seen, SelectionOptions(margin), seen_cos)
    faces = np.flatnonzero(region)
    Vs, Fs, kept = submesh(V, F, faces)
    unpinched, _ = split_along(Fs, len(Vs))
    rims = len(boundary_loops(unpinched))
    e_count = len(unique_edges(unpinched)[0])
    genus = (2 - rims - (len(np.unique(unpinched)) - e_count + len(Fs))) // 2
    try:
        Fd, source, seams = surface_cut.cut_to_disc(Vs, Fs, seen_cos[faces])
    except WorkbenchError as exc:
        raise WorkbenchError(f"{name}: the decorated surface: {exc}") from None
    Vd = Vs[source]
    lengths = [path_length(Vs, s) for s in seams]
    report = {
        "mode": "faces file" if isinstance(mode, Path) else mode,
        **({"faces_file": mode.name} if isinstance(mode, Path) else {}),
        **sel.to_dict(),
        "rims": rims,
        "genus": genus,
        "seams": {
            "count": len(seams),
            "length_mm": float(sum(lengths)),
            "lengths_mm": lengths,
            "joining_rims": rims - 1,
            "across_handles": 2 * genus,
            "vertices": [[int(v) for v in s] for s in seams],
        },
        "disc": {"vertices": len(Vd), "faces": len(Fd), "euler_characteristic": 1},
        **({"refined": refined} if refined else {}),
        "warnings": [],
    }
    if sel.islands_over_limit_mm2 > 0:
        report["warnings"].append(
            f"{sel.islands_over_limit_mm2:.0f} mm² the views see lie apart from the decorated surface and are "
            "left bare (one film is one piece): a view of them alone, or films, would print them"
        )
    say(f"surface cut out of {name.name}: {len(Fd)} of {len(F)} faces, {len(seams)} seams")
    report["picture"] = selection_picture(
        V, F, sel.face_class, cameras, job, [kept[np.asarray(s_)] for s_ in seams], report, mode
    )
    return Vd, Fd, report


def selection_picture(V, F, face_class, cameras, job: Job, seams, report: dict, mode) -> bytes:
    """``surface.png``: the part from each view, what is printed coloured by why, the seams red."""
    per = np.bincount(face_class, weights=face_areas(V, F), minlength=len(CLASS_WORDS))
    words = list(CLASS_WORDS)
    if isinstance(mode, Path):
        words[SEEN] = f"in {mode.name}"
    legend = [(k, f"{words[k]}: {per[k]:.0f} mm²") for k in range(len(words)) if per[k] > 0]
    title = f"{job.name}: the surface printed, and why\n{surface_line(report)}"
    title = "\n".join(textwrap.fill(t, 110) for t in title.split("\n"))
    names = [f"view {v.name}" for v in job.views]
    # and from the far side, where the margin ends and nothing is printed: opposite the views'
    # mean direction, at their mean distance, the part's bounding sphere filling the frame
    centre = 0.5 * (V.min(axis=0) + V.max(axis=0))
    eyes = np.array([c.center for c in cameras]) - centre
    towards = eyes.mean(axis=0)
    if np.linalg.norm(towards) > 1e-9 * np.linalg.norm(eyes):
        d = float(np.linalg.norm(eyes, axis=1).mean())
        radius = float(np.linalg.norm(V - centre, axis=1).max())
        back = centre - d * towards / np.linalg.norm(towards)
        # (up: the mesh's +z, unless the far side looks along it)
        up = np.array([0.0, 0.0, 1.0]) if abs(towards[2]) < 0.9 * np.linalg.norm(towards) else np.array([0.0, 1.0, 0.0])
        fov = float(np.degrees(2 * np.arcsin(min(1.1 * radius / d, 0.95))))
        cameras = [*cameras, Camera.look_at(back, centre, up, fov, cameras[0].width, cameras[0].width)]
        names.append("the far side")
    return surface_figure(V, F, face_class, cameras, names, seams, legend, title)


def surface_line(report: dict) -> str:
    """One line saying what of the mesh was selected and cut (design.json's ``surface``)."""
    r, seams = report, report["seams"]
    return (
        f"surface: {100 * r['selected_share']:.1f} % of the mesh ({r['selected_mm2']:.0f} mm², "
        f"{r['selected_faces']} faces): seen {100 * r['seen_share']:.1f} %, margin {r['margin_mm']:g} mm "
        f"({r['margin_mm2']:.0f} mm²), {r['holes_filled']} holes filled ({r['holes_filled_mm2']:.0f} mm²), "
        f"{r['islands_dropped']} islands dropped ({r['islands_dropped_mm2']:.0f} mm²); "
        f"{seams['count']} seams, {seams['length_mm']:.1f} mm"
    )

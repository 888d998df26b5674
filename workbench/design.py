"""The paper's method end to end: views, conformal map, per-pixel print synthesis."""

from __future__ import annotations

import hashlib
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from workbench.camera import Camera
from workbench.closed_surface import decorated_surface, surface_mode
from workbench.conformal.distortion import flat_to_surface_singular_values
from workbench.conformal.flatten import (
    CrowdingError,
    FlattenOptions,
    FlattenResult,
    ScaleMode,
    crowding_advice,
    flatten,
    flatten_auto_corners,
)
from workbench.conformal.layout import signed_areas
from workbench.design_dir import read_image as read_image  # lives with the design folder's reading
from workbench.environment import proc_bytes
from workbench.errors import WorkbenchError
from workbench.films.regions import cut_to_disc, disc_region, face_graph, is_disc, submesh
from workbench.films.sheet import pack_films, seams
from workbench.films.split import split_films
from workbench.job import Job, Material
from workbench.job_views import assign_job_views, read_view_images, region_warnings
from workbench.mesh.caps import flip_caps
from workbench.mesh.io import MeshName, read_mesh
from workbench.mesh.selection import read_face_list
from workbench.mesh.validate import face_areas
from workbench.texture.outline import film_mask
from workbench.texture.synthesis import PrintGrid, synthesize_print
from workbench.views.visibility import (
    ViewVisibility,
)

# bytes per print pixel at the peak: RGB + owner map + film mask + the PNG encoder's copy and output
BYTES_PER_PRINT_PIXEL = 12


@dataclass
class DesignResult:
    """Everything ``workbench design`` computes.

    Attributes
    ----------
    V : (#V, 3) float
        Mesh vertices, mm.
    F : (#F, 3) int
        Triangles.
    flat : FlattenResult
        Conformal map and stretch.
    grid : PrintGrid
        Print pixels.
    rgb : (rows, cols, 3) uint8
        The print.
    owner : (rows, cols) int8
        Owning view per print pixel, -1 for background (and outside the film).
    film : (rows, cols) bool
        Pixels on the film: inside its outline (all of them for a rectangle).
    cameras : list of Camera
        Designed views' cameras, in priority order.
    status : (#F, #views) int8
        Face ownership (see :func:`workbench.views.visibility.assign_views`).
    visibilities : list of ViewVisibility
        Depth buffers and visible faces per view.
    view_px_per_print_px : list of float
        Per view, view pixels per print pixel (linear).
    timings_s : dict
        Seconds per stage.
    view_status : (#Fv, #views) int8
        Ownership on the mesh the views' depth buffers were made of (the input mesh
        with several films, else ``status``).
    films : list of Film
        With several films, each film; then ``rgb``, ``owner``, ``film``, ``grid``,
        ``V``, ``F`` and ``flat`` are their atlas: the films side by side on one
        sheet, each film's own mesh (seam vertices repeated), what render and
        validate read.
    seams : dict or None
        With several films, :func:`workbench.films.sheet.seams` on the input mesh.
    undecorated : (mm², share)
        The surface no view owns (:func:`undecorated_surface`), on the mesh the views
        were assigned on.
    """

    V: np.ndarray
    F: np.ndarray
    flat: FlattenResult
    grid: PrintGrid
    rgb: np.ndarray
    owner: np.ndarray
    film: np.ndarray
    cameras: list[Camera]
    status: np.ndarray
    visibilities: list[ViewVisibility]
    view_px_per_print_px: list[float]
    timings_s: dict = field(default_factory=dict)
    view_status: np.ndarray | None = None
    films: list[Film] = field(default_factory=list)
    seams: dict | None = None
    # plausibility warnings found on the way (films that cover little of what they were given)
    warnings: list[str] = field(default_factory=list)
    undecorated: tuple[float, float] = (0.0, 0.0)
    compensation: object = None  # workbench.forming.Compensation, with a forming profile
    # with a surface cut out of the mesh (a closed part, or [object] surface): what was selected
    # and cut, and why (:func:`decorated_surface`); None when the mesh is the surface
    surface: dict | None = None
    surface_picture: bytes | None = None  # surface.png: the part from each view, what is printed and why


def undecorated_surface(V: np.ndarray, F: np.ndarray, status: np.ndarray) -> tuple[float, float]:
    """The surface no view owns: faces no view claims, even in part.

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        Triangles.
    status : (#F, #views) int8
        Ownership (:func:`workbench.views.visibility.assign_views`).

    Returns
    -------
    mm2 : float
        Its area, mm².
    share : float
        Its share of the surface.
    """
    area = face_areas(V, F)
    left = float(area[~(status != 0).any(axis=1)].sum())
    return left, left / max(float(area.sum()), 1e-300)


@dataclass
class Film:
    """One film of a design with several.

    Attributes
    ----------
    name : str
    faces : (k,) int
        Input faces it covers.
    flat : FlattenResult
        Its map (of its submesh, in the submesh's numbering).
    grid : PrintGrid
        Its print's pixels.
    rgb : (rows, cols, 3) uint8
        Its print.
    owner : (rows, cols) int8
        Owning view per pixel, -1 none.
    film : (rows, cols) bool
        Inside its outline.
    material : Material
    outline : str
    atlas_px : (row, col)
        Its print's top-left pixel in the atlas.
    atlas_faces : (start, stop)
        Its faces in the atlas mesh.
    within : float
        Share of its surface within [0.8, max_stretch].
    compensation : Compensation or None
        Its pre-compensation for a forming profile (its own print's frame offset, base size, moves).
    """

    name: str
    faces: np.ndarray
    flat: FlattenResult
    grid: PrintGrid
    rgb: np.ndarray
    owner: np.ndarray
    film: np.ndarray
    material: Material
    outline: str
    atlas_px: tuple[int, int] = (0, 0)
    atlas_faces: tuple[int, int] = (0, 0)
    within: float = float("nan")
    compensation: object = None  # workbench.forming.Compensation, with a forming profile


# free pixels between films on the atlas, mm
ATLAS_GAP_MM = 5.0


def _film_regions(
    job: Job, V, F, status, say, warnings: list[str], cover_all: bool = False
) -> list[tuple[str, np.ndarray, FlattenResult, Material, str]]:
    """Faces and map of each film: split automatically, or as the job gives them.

    Appends to ``warnings`` a film that keeps less than MIN_FILM_COVERAGE of the faces it
    was given (one film is one connected disc: faces that meet only at corners are cut to
    the largest piece) and decorated faces left on no film beyond MAX_BARE_SHARE.
    """
    area = face_areas(V, F)
    owned = status != 0
    owner_view = np.where(owned.any(axis=1), np.argmax(owned, axis=1), -1)
    min_print = 0.5 * 25.4 / job.print.dpi
    if job.films == "auto":
        limit = job.object.material.max_stretch
        # (a surface cut out of a closed part is printed whole: its margin reaches past what the
        # views own so that the film's rim lies beyond what they see)
        covered = np.ones(len(F), bool) if cover_all else owner_view >= 0
        fits = split_films(
            V,
            F,
            covered,
            owner_view,
            limit,
            FlattenOptions(min_print_mm=min_print),
            log=say,
            within_share=job.object.material.within_share,
        )
        return [(f"film-{k + 1}", f.faces, f.flat, job.object.material, "free") for k, f in enumerate(fits)]
    graph = face_graph(F)
    claimed = np.zeros(len(F), bool)
    out = []
    names = [v.name for v in job.views]
    for i, spec in enumerate(job.films):
        where = f"{job.path}: films[{i}] ({spec.name!r})"
        if spec.views is not None:
            wanted = np.isin(owner_view, [names.index(v) for v in spec.views])
        else:
            wanted = np.zeros(len(F), bool)
            wanted[_read_faces(spec.faces, len(F), where)] = True
        wanted &= ~claimed
        if not wanted.any():
            raise WorkbenchError(f"{where}: covers no face (earlier films took them, or its views own none)")
        try:
            region = disc_region(F, wanted, area, allowed=~claimed, graph=graph, keep_holes=True)
            faces = np.flatnonzero(region)
            Vs, Fs, vertices = submesh(V, F, faces)
            if not is_disc(Fs):
                # a ring around an earlier film: cut open along the shortest path between its rims
                Vs, Fs, source = cut_to_disc(Vs, Fs)
                vertices = vertices[source]
                say(f"film {spec.name}: a ring around another film, cut open to a disc")
        except WorkbenchError as exc:
            raise WorkbenchError(f"{where}: {exc}") from None
        corners = None
        if spec.corners is not None:
            local = [np.flatnonzero(vertices == c) for c in spec.corners]
            if any(len(x) != 1 for x in local):
                raise WorkbenchError(f"{where}: corners: a corner vertex is not on this film's surface once")
            corners = tuple(int(x[0]) for x in local)
        scale = job.print.scale if spec.outline == job.print.outline else ScaleMode.default(spec.outline)
        options = FlattenOptions(corners=corners, scale=scale, min_print_mm=min_print, outline=spec.outline)
        try:
            flat = flatten(Vs, Fs, options, where, log=say)
        except CrowdingError as exc:
            raise crowding_advice(exc, Vs, Fs, options, where, say) from None
        kept = float(area[region & wanted].sum() / area[wanted].sum())
        if kept < MIN_FILM_COVERAGE:
            warnings.append(
                f"film {spec.name!r} keeps {100 * kept:.1f} % of the surface it was given "
                f"({area[region & wanted].sum():.1f} of {area[wanted].sum():.1f} mm²): a film is one piece, "
                "and faces that meet only at corners (or not at all) are not one piece"
            )
        claimed |= region
        out.append((spec.name, faces, flat, spec.material, spec.outline))
    left = (owner_view >= 0) & ~claimed
    decorated = float(area[owner_view >= 0].sum())
    if decorated > 0 and area[left].sum() > MAX_BARE_SHARE * decorated:
        warnings.append(
            f"{100 * area[left].sum() / decorated:.1f} % of the decorated surface ({area[left].sum():.0f} mm²) "
            "is on no film: the part would be left bare there"
        )
    elif left.any():
        say(f"{int(left.sum())} decorated faces ({area[left].sum():.0f} mm²) are on no film")
    return out


def _read_faces(path, n_faces: int, where: str) -> np.ndarray:
    """0-based face indices from a text file, checked against the mesh."""
    return read_face_list(path, n_faces, f"{where}: faces")


def _design_films(
    job: Job,
    V,
    F,
    images,
    say,
    t,
    forming_profile: Path | None = None,
    decorations: list | None = None,
    cover_all: bool = False,
) -> DesignResult:
    """The design with several films: views on the whole part, one map and print per film, their atlas.

    With a forming profile, each film's map is pre-compensated by that film's field (films are
    formed one by one, each on its own print) before its print is synthesised. With
    ``cover_all`` (a surface cut out of a closed part: what the views see and its margin)
    ``films = "auto"`` covers every face, the margin no view owns included.
    """
    t0 = time.perf_counter()
    cameras, visibilities, status = assign_job_views(job, V, F, images, decorations)
    t["views"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    warnings: list[str] = region_warnings(job, visibilities, status, face_areas(V, F))
    regions = _film_regions(job, V, F, status, say, warnings, cover_all)
    t["flatten"] = time.perf_counter() - t0
    comps: list = [None] * len(regions)
    if forming_profile is not None:
        t0 = time.perf_counter()
        prof = read_checked_profile(job, forming_profile, [r[2] for r in regions], [r[0] for r in regions])
        for k, (name, faces, flat, material, outline) in enumerate(regions):
            flat, comps[k] = compensate_flat(job, flat, prof, k, forming_profile)
            regions[k] = (name, faces, flat, material, outline)
            say(
                f"film {name}: forming profile {forming_profile.name}: print moved by up to "
                f"{comps[k].moved_mm.max():.3f} mm, frame grown by {list(comps[k].frame_offset_px)} px"
            )
        t["forming compensation"] = time.perf_counter() - t0
    owned = status != 0
    film_of_face = np.full(len(F), -1)
    for k, (_, faces, _, _, _) in enumerate(regions):
        film_of_face[faces] = k
    seam = seams(F, V, film_of_face, np.where(owned.any(axis=1), np.argmax(owned, axis=1), -1))
    say(f"{len(regions)} films; seams {seam['length_mm']:.0f} mm, {seam['in_view_mm']:.0f} mm of them inside a view")

    t0 = time.perf_counter()
    films: list[Film] = []
    scales = np.zeros(len(job.views))
    for (name, faces, flat, material, outline), comp in zip(regions, comps, strict=True):
        grid = PrintGrid(flat.width_mm, flat.height_mm, job.print.dpi)
        check_print_fits(grid, f"{job.path}: [print].dpi (film {name})")
        sub_status = status[faces][flat.parent]
        rgb, owner, s = synthesize_print(
            grid, flat.uv, flat.V, flat.F, sub_status, visibilities, images, job.print.background
        )
        rows, cols = grid.shape
        if outline == "rectangle" and comp is None:
            inside = np.ones((rows, cols), bool)
        else:
            # (a compensated film's outline is its own, pre-distorted)
            inside = film_mask(grid.to_pixels(flat.uv), flat.F, rows, cols)
        ok = ~flat.collapsed
        hi = material.max_stretch or np.inf
        within = float(flat.area_3d[ok & (flat.stretch >= 0.8) & (flat.stretch <= hi)].sum() / flat.area_3d.sum())
        films.append(
            Film(name, faces, flat, grid, rgb, owner, inside, material, outline, within=within, compensation=comp)
        )
        scales = np.maximum(scales, s)

    # the atlas: every film's print on one sheet, every film's mesh (seams repeated)
    ppm = job.print.dpi / 25.4
    offsets, (rows, cols) = pack_films([f.grid.shape for f in films], int(np.ceil(ATLAS_GAP_MM * ppm)))
    check_print_fits(PrintGrid(cols / ppm, rows / ppm, job.print.dpi), f"{job.path}: [print].dpi (all films)")
    rgb = np.empty((rows, cols, 3), np.uint8)
    rgb[:] = job.print.background
    owner = np.full((rows, cols), -1, np.int8)
    inside = np.zeros((rows, cols), bool)
    height_mm = rows / ppm
    Vs, Fs, uvs, parents, sig, areas, coll, crowd, st = [], [], [], [], [], [], [], [], []
    nv = nf = 0
    for f, (r0, c0) in zip(films, offsets, strict=True):
        fr, fc = f.grid.shape
        rgb[r0 : r0 + fr, c0 : c0 + fc][f.film] = f.rgb[f.film]
        owner[r0 : r0 + fr, c0 : c0 + fc][f.film] = f.owner[f.film]
        inside[r0 : r0 + fr, c0 : c0 + fc] |= f.film
        # pixel (i, j) of the film is atlas pixel (r0 + i, c0 + j): x + c0 / ppm, and y up
        # measured from the atlas's bottom edge instead of the film's
        shift = np.array([c0 / ppm, height_mm - r0 / ppm - f.flat.height_mm])
        Vs.append(f.flat.V)
        Fs.append(f.flat.F + nv)
        uvs.append(f.flat.uv + shift)
        parents.append(f.faces[f.flat.parent])
        sig.append(f.flat.sigma)
        areas.append(f.flat.area_3d)
        coll.append(f.flat.collapsed)
        crowd.append(f.flat.crowded)
        st.append(status[f.faces][f.flat.parent])
        f.atlas_px, f.atlas_faces = (r0, c0), (nf, nf + len(f.flat.F))
        nv, nf = nv + len(f.flat.V), nf + len(f.flat.F)
    worst = max(films, key=lambda f: f.flat.newton.residual_rad)
    atlas = replace(
        films[0].flat,
        V=np.concatenate(Vs),
        F=np.concatenate(Fs),
        parent=np.concatenate(parents),
        n_input_vertices=len(V),
        uv=np.concatenate(uvs),
        corners=np.zeros(0, np.int64),
        corner_rule=f"{len(films)} films",
        width_mm=cols / ppm,
        height_mm=height_mm,
        newton=worst.flat.newton,
        sigma=np.concatenate(sig),
        area_3d=np.concatenate(areas),
        flipped_faces=sum(f.flat.flipped_faces for f in films),
        collapsed=np.concatenate(coll),
        crowded=np.concatenate(crowd),
        intrinsic_flips=sum(f.flat.intrinsic_flips for f in films),
    )
    t["synthesis"] = time.perf_counter() - t0
    say(f"atlas of {len(films)} films: {cols} x {rows} px")
    return DesignResult(
        V=atlas.V,
        F=atlas.F,
        flat=atlas,
        grid=PrintGrid(cols / ppm, height_mm, job.print.dpi),
        rgb=rgb,
        owner=owner,
        film=inside,
        cameras=cameras,
        status=np.concatenate(st),
        visibilities=visibilities,
        view_px_per_print_px=scales.tolist(),
        timings_s=t,
        view_status=status,
        films=films,
        seams=seam,
        warnings=warnings,
        undecorated=undecorated_surface(V, F, status),
    )


def physical_memory() -> int:
    """The memory this command can have, bytes: what Linux says is available, else the machine's (16 GiB
    where the system does not say). Available, not installed: on a shared machine the rest is in use."""
    if (available := proc_bytes("/proc/meminfo", "MemAvailable")) is not None:
        return available
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 16 * 2**30


def check_print_fits(grid: PrintGrid, where: str) -> None:
    """Refuse, before allocating, a print that would not fit in this machine's memory."""
    rows, cols = grid.shape
    need = rows * cols * BYTES_PER_PRINT_PIXEL
    have = physical_memory()
    if need > 0.7 * have:
        raise WorkbenchError(
            f"{where}: a {grid.width_mm:.1f} x {grid.height_mm:.1f} mm print at {grid.dpi:g} dpi is "
            f"{cols:,} x {rows:,} px ({rows * cols / 1e6:,.0f} Mpx) and needs about {need / 2**30:,.1f} GiB; "
            f"this machine has {have / 2**30:.1f} GiB available: lower [print].dpi"
        )


def profile_identity(job: Job) -> dict:
    """What a forming profile must have been measured for, known before the map: mesh, dpi (and, with
    one film, its name; several films are named once split)."""
    out = {
        "mesh_sha256": hashlib.sha256(job.object.mesh.read_bytes()).hexdigest(),
        "dpi": float(job.print.dpi),
    }
    if job.films is None:
        out["films"] = ["film-1"]
    return out


def compensate_flat(job: Job, flat: FlattenResult, prof: dict, film: int, path: Path):
    """One film's flat layout pre-compensated by film ``film`` of the forming profile ``prof`` (read from
    ``path``; its print size checked against this film's)."""
    from workbench import forming as fm

    comp = fm.compensate_layout(flat.uv, flat.width_mm, flat.height_mm, job.print.dpi, fm.profile_field(prof, film))
    comp.base = (flat.width_mm, flat.height_mm)
    comp.profile = path
    comp.round = int(prof["design"].get("round", 1))
    sigma = np.full_like(flat.sigma, np.nan)
    ok = ~flat.collapsed
    # the compensated map's stretch: what the film must do to land as the design wants
    sigma[ok] = flat_to_surface_singular_values(flat.V, flat.F[ok], comp.uv)
    new = replace(flat, uv=comp.uv, width_mm=comp.width_mm, height_mm=comp.height_mm, sigma=sigma)
    return new, comp


def read_checked_profile(job: Job, path: Path, films: list[FlattenResult] | None = None, names=None) -> dict:
    """The forming profile at ``path``, checked against this job: mesh, dpi, material; once the films'
    maps are known (``films``, ``names``), their names and uncompensated print sizes."""
    from workbench import forming as fm

    prof = fm.read_profile(path)
    identity = profile_identity(job)
    if films is not None:
        identity["films"] = list(names)
        if job.films is None:
            identity["width_mm"] = round(float(films[0].width_mm), 6)
            identity["height_mm"] = round(float(films[0].height_mm), 6)
        else:
            identity["film_sizes_mm"] = [[round(float(f.width_mm), 6), round(float(f.height_mm), 6)] for f in films]
    fm.check_profile_for(prof, identity, job.object.material.name, str(path))
    return prof


def design(job: Job, log: Callable[[str], None] | None = None, forming_profile: Path | None = None) -> DesignResult:
    """Compute the print of a job.

    Parameters
    ----------
    job : Job
        Parsed job file.
    log : callable(str), optional
        Receives progress lines.

    Returns
    -------
    DesignResult

    Raises
    ------
    WorkbenchError
        Bad mesh, unreadable images, a camera with the part behind it, a view that
        sees nothing, or a print too large for memory.
    """
    say = log or (lambda _m: None)
    forming_profile = forming_profile or job.object.forming_profile
    t: dict[str, float] = {}
    t0 = time.perf_counter()
    V, F = read_mesh(job.object.mesh, job.object.units, log=say)
    # (a scan's triangles with a corner on their opposite edge: no map flattens them, and flipped
    # with their neighbour the surface is the same)
    F, caps = flip_caps(V, F)
    if caps:
        say(f"{job.object.mesh.name}: {caps} faces of zero area (a corner on the opposite edge) flipped")
    images, decorations = read_view_images(job)
    t["read"] = time.perf_counter() - t0
    say(f"read {job.object.mesh.name}: {len(V)} vertices, {len(F)} faces; {len(images)} view images")
    # said with the fit's warnings at the end (and refused by --strict there)
    implausible = view_image_warnings(
        images, [f"{job.path}: views[{i}].image" for i in range(len(images))], decorations
    )
    surface, surface_picture = None, None
    if surface_mode(job, F) != "whole":
        t0 = time.perf_counter()
        V, F, surface = decorated_surface(job, V, F, images, say, decorations)
        t["surface"] = time.perf_counter() - t0
        implausible += surface.pop("warnings")
        surface_picture = surface.pop("picture")

    if forming_profile is not None:
        # before the minutes of work: a profile of another part, dpi or material
        read_checked_profile(job, forming_profile)
    if job.films is not None:
        result = _design_films(job, V, F, images, say, t, forming_profile, decorations, surface is not None)
        result.warnings[:0] = implausible
        result.surface, result.surface_picture = surface, surface_picture
        return result

    t0 = time.perf_counter()
    auto = job.object.corners == "auto"
    options = FlattenOptions(
        corners=None if auto else job.object.corners,
        corners_from=f"{job.path}: object.corners",
        scale=job.print.scale,
        min_print_mm=0.5 * 25.4 / job.print.dpi,
        outline=job.print.outline,
    )
    if auto and job.print.outline == "rectangle":
        flat, _ = flatten_auto_corners(V, F, options, str(job.object.mesh), log=say)
    else:
        try:
            flat = flatten(V, F, options, MeshName(job.object.mesh), log=say)
        except CrowdingError as exc:
            raise crowding_advice(exc, V, F, options, str(job.object.mesh), say) from None
    t["flatten"] = time.perf_counter() - t0
    compensation = None
    if forming_profile is not None:
        t0 = time.perf_counter()
        prof = read_checked_profile(job, forming_profile, [flat], ["film-1"])
        flat, compensation = compensate_flat(job, flat, prof, 0, forming_profile)
        t["forming compensation"] = time.perf_counter() - t0
        say(
            f"forming profile {forming_profile.name}: print moved by up to {compensation.moved_mm.max():.3f} mm, "
            f"frame grown by {list(compensation.frame_offset_px)} px"
        )
    # from here on the part is the flattened mesh: the input, or its common subdivision
    # with the flat triangulation (input vertices first), on which the map is exact
    V, F = flat.V, flat.F
    grid = PrintGrid(flat.width_mm, flat.height_mm, job.print.dpi)
    check_print_fits(grid, f"{job.path}: [print].dpi")

    t0 = time.perf_counter()
    cameras, visibilities, status = assign_job_views(job, V, F, images, decorations)
    implausible += region_warnings(job, visibilities, status, face_areas(V, F))
    t["views"] = time.perf_counter() - t0
    say("views: " + ", ".join(f"{s.name} {int((status[:, i] != 0).sum())} faces" for i, s in enumerate(job.views)))

    t0 = time.perf_counter()
    rows, cols = grid.shape
    say(f"synthesising {cols} x {rows} px print at {job.print.dpi:g} dpi ({rows * cols / 1e6:.1f} Mpx)")
    rgb, owner, scales = synthesize_print(grid, flat.uv, V, F, status, visibilities, images, job.print.background)
    if job.print.outline == "rectangle" and compensation is None:
        film = np.ones((rows, cols), dtype=bool)
    else:
        # (a compensated film's outline is the rectangle's, pre-distorted)
        film = film_mask(grid.to_pixels(flat.uv), F, rows, cols)
    t["synthesis"] = time.perf_counter() - t0
    return DesignResult(
        warnings=implausible,
        compensation=compensation,
        V=V,
        F=F,
        flat=flat,
        grid=grid,
        rgb=rgb,
        owner=owner,
        film=film,
        cameras=cameras,
        status=status,
        visibilities=visibilities,
        view_px_per_print_px=scales,
        timings_s=t,
        view_status=status,
        undecorated=undecorated_surface(V, F, status),
        surface=surface,
        surface_picture=surface_picture,
    )


def view_statistics(result: DesignResult, names: list[str]) -> list[dict]:
    """Per view: faces and surface owned, share of the print, share of its image used.

    Parameters
    ----------
    result : DesignResult
        A computed design.
    names : list of str
        View names, priority order.

    Returns
    -------
    list of dict
    """
    area = face_areas(result.V, result.F)
    first = np.argmax(result.status != 0, axis=1)
    owned_any = (result.status != 0).any(axis=1)
    rows, cols = result.grid.shape
    stats = []
    for v, name in enumerate(names):
        mine = owned_any & (first == v)
        fb = result.visibilities[v].face_buffer
        seen = fb >= 0
        used = np.zeros_like(seen)
        vs = result.status if result.view_status is None else result.view_status
        used[seen] = vs[fb[seen], v] != 0
        if result.visibilities[v].decoration is not None:
            used &= result.visibilities[v].decoration  # its transparent pixels are not used
        stats.append(
            {
                "name": name,
                "faces_owned": int(mine.sum()),
                "surface_owned_mm2": float(area[mine].sum()),
                # of the film: pixels outside a free outline are not printed
                "print_share": float((result.owner == v).sum() / max(int(result.film.sum()), 1)),
                "image_share_used": float(used.mean()),
                "view_px_per_print_px": result.view_px_per_print_px[v],
                "camera": result.cameras[v].to_dict(),
            }
        )
    return stats


# The film fits the part when its stretch stays within [MIN_STRETCH, material limit]
# almost everywhere (film stretches; it barely shrinks), the print is mostly part, and
# the print is not much larger than the part's developed area.
MIN_STRETCH = 0.8
MAX_OFF_STRETCH_SHARE = 0.01
MAX_BACKGROUND_SHARE = 0.5
MAX_PRINT_TO_SURFACE = 2.0
# films: the share of the surface a film was given that it must keep, and the share of the
# decorated surface that may stay on no film
MIN_FILM_COVERAGE = 0.9
MAX_BARE_SHARE = 0.02
# below this, a print pixel (or a view pixel on the print) is over 2.5 mm: no detail survives
# (the tests' quick designs print at 20 to 50 dpi, a coarse but legible preview)
MIN_DPI = 10.0
# a view that paints less of the print than this is not judged by its resolution
MIN_VIEW_SHARE = 0.01


def background_share(result: DesignResult) -> float:
    """Share of the film's pixels that no view owns (pixels outside a free outline are not film)."""
    return float((result.owner[result.film] < 0).mean()) if result.film.any() else 1.0


def film_area_mm2(flat: FlattenResult) -> float:
    """Area of the film inside its outline, mm² (the rectangle's, or the free outline's)."""
    return float(np.abs(signed_areas(flat.uv, flat.F)).sum())


# a view image's largest side over its smallest beyond which it is taken for a mistake: cameras
# make 1:1 to 1:4 (a panorama about 1:8); a 400000 x 2 px image is a line, not a view
MAX_VIEW_ASPECT = 20.0
# the peak-to-peak grey levels under which a view image is one flat colour (8-bit JPEG noise on a
# flat area is 1 to 2 levels)
FLAT_IMAGE_LEVELS = 2


def view_image_warnings(
    images: list[np.ndarray], names: list[str], decorations: list[np.ndarray | None] | None = None
) -> list[str]:
    """Why a view image looks like a mistake, one sentence each; empty when none does.

    Parameters
    ----------
    images : list of (H, W, 3) uint8
        The view images, RGB.
    names : list of str
        What to call each (the job key).
    decorations : list of (H, W) bool or None, optional
        Per view, its decoration pixels (:func:`read_view_images`).

    Returns
    -------
    list of str
        An image of one flat colour (no picture to print; not said of a view whose alpha or
        mask marks its decoration: a one-colour logo's picture is its shape), an aspect beyond
        MAX_VIEW_ASPECT.
    """
    out = []
    decorations = decorations or [None] * len(images)
    for img, name, decoration in zip(images, names, decorations, strict=True):
        h, w = img.shape[:2]
        if max(h, w) > MAX_VIEW_ASPECT * min(h, w):
            out.append(
                f"{name} is {w} x {h} px, an aspect of {max(h, w) / min(h, w):.0f}:1: a camera's picture is at most "
                f"about 8:1 (a panorama); beyond {MAX_VIEW_ASPECT:g}:1 it is taken for a mistake"
            )
        span = img.reshape(-1, img.shape[-1])
        spread = int((span.max(axis=0).astype(int) - span.min(axis=0)).max())
        if spread <= FLAT_IMAGE_LEVELS and decoration is None:
            rgb = tuple(int(c) for c in span[0])
            out.append(
                f"{name} is one flat colour (every pixel within {FLAT_IMAGE_LEVELS} grey levels of RGB {rgb}): "
                "there is no picture to print from it"
            )
    return out


def fit_warnings(result: DesignResult, max_stretch: float | None, names: list[str] | None = None) -> list[str]:
    """Why this print will not make a good part, one sentence each; empty when it will.

    Parameters
    ----------
    result : DesignResult
        A computed design.
    max_stretch : float or None
        The material's stretch limit (3D length / print length); None: no upper check.
    names : list of str, optional
        The views' names, for the warnings about them.

    Returns
    -------
    list of str
        Warnings: stretch outside [0.8, limit] on more than 1 % of the surface,
        background over half the print, a print more than twice the developed area, a
        print below MIN_DPI, a view image that paints its share of the print below
        MIN_DPI (effective resolution: view pixels per print mm), and the films' own
        (a film that keeps little of its faces, surface on no film).
    """
    flat = result.flat
    ok = ~flat.collapsed
    area, stretch = flat.area_3d[ok], flat.stretch[ok]
    surface = float(flat.area_3d.sum())
    hi = np.inf if max_stretch is None else max_stretch
    off = float(area[(stretch < MIN_STRETCH) | (stretch > hi)].sum() + flat.area_3d[flat.collapsed].sum())
    out = []
    if off > MAX_OFF_STRETCH_SHARE * surface:
        band = f"[{MIN_STRETCH:g}, {'∞' if max_stretch is None else f'{max_stretch:g}'}]"
        out.append(
            f"the film stretch leaves {band} on {100 * off / surface:.1f} % of the surface "
            f"(from {np.nanmin(stretch):.3g} to {np.nanmax(stretch):.3g}): the film would tear or wrinkle there"
        )
    background = background_share(result)
    if background > MAX_BACKGROUND_SHARE:
        out.append(f"background is {100 * background:.1f} % of the print: the outline does not fit the part")
    film_area = film_area_mm2(flat)
    if film_area > MAX_PRINT_TO_SURFACE * surface:
        out.append(
            f"the print ({flat.width_mm:.0f} x {flat.height_mm:.0f} mm, {film_area / 100:.0f} cm² of film) is "
            f"{film_area / surface:.1f} times the part's developed area"
        )
    dpi = result.grid.dpi
    if dpi < MIN_DPI:
        out.append(
            f"the print's {dpi:g} dpi makes pixels of {25.4 / dpi:.2g} mm: below {MIN_DPI:g} dpi no detail shows"
        )
    n_film = max(int(result.film.sum()), 1)
    for v, s in enumerate(result.view_px_per_print_px):
        share = float((result.owner == v).sum() / n_film)
        effective = float(s) * dpi  # view pixels per inch of print
        if share >= MIN_VIEW_SHARE and not effective >= MIN_DPI:
            name = names[v] if names and v < len(names) else str(v)
            out.append(
                f"view {name!r} paints {100 * share:.1f} % of the print at {effective:.2g} dpi (one view pixel "
                f"spans {25.4 / max(effective, 1e-9):.3g} mm of print): its image is too small for the print "
                f"(at least {MIN_DPI:g} dpi)"
            )
    out.extend(result.warnings)
    return out

"""``workbench design``: a job file in, the print texture and the decorated mesh out."""

from __future__ import annotations

import hashlib
import json
import sys
import textwrap
import time
from pathlib import Path

import numpy as np

from workbench import __version__
from workbench.atomic import check_output_dir, safe_name, write_folder
from workbench.closed_surface import surface_line
from workbench.commands.flatten import summary
from workbench.conformal.distortion import weighted_quantiles
from workbench.design import (
    background_share,
    design,
    film_area_mm2,
    fit_warnings,
    read_image,
    view_statistics,
)
from workbench.errors import WorkbenchError
from workbench.export import decorated_glb, decorated_obj, png_bytes, texture_uv
from workbench.figures import stretch_figure, views_figure
from workbench.films.fit import MIN_STRETCH, outside_band
from workbench.image_file import exif_orientation
from workbench.job import load_job
from workbench.jsonfile import recorded_path
from workbench.mesh.io import format_obj
from workbench.printing.boards import colour_chart_from_job, definition, fixture_from_job


def add_parser(sub) -> None:
    p = sub.add_parser(
        "design",
        help="compute the print of a job: multi-view projective texture on a conformal map",
        description=(
            "Compute one print from a job file (mesh + views in priority order). Writes DIR/print.png "
            "(with its dpi), decorated.obj/.mtl and decorated.glb (the part textured with the print), "
            "flat.obj, design.json, views.png (which view owns each print pixel) and stretch.png."
        ),
    )
    p.add_argument("job", metavar="JOB.toml", help="job file (see README: Job file)")
    p.add_argument("--out", metavar="DIR", help="output directory (default: design-<job name>)")
    p.add_argument(
        "--strict",
        action="store_true",
        help="treat a print that does not fit the part (stretch, background, size warnings) as an error: "
        "exit 1, nothing written",
    )
    p.add_argument(
        "--forming-profile",
        metavar="PROFILE.json",
        help="pre-compensate the print for how the film really lands (workbench calibrate forming); "
        "overrides [object] forming_profile",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


def film_records(result) -> list[dict]:
    """design.json's ``films``: one record per film."""
    seam = result.seams
    records = []
    for k, f in enumerate(result.films):
        ok = ~f.flat.collapsed
        q = weighted_quantiles(f.flat.stretch[ok], f.flat.area_3d[ok], [0.0, 0.5, 1.0])
        records.append(
            {
                "name": f.name,
                "film": f"{k + 1} of {len(result.films)}",
                "print": f"print-{f.name}.png",
                "flat": f"flat-{f.name}.obj",
                "outline": f.outline,
                "faces": int(len(f.faces)),
                "surface_mm2": float(f.flat.area_3d.sum()),
                "width_mm": f.flat.width_mm,
                "height_mm": f.flat.height_mm,
                "width_px": f.grid.shape[1],
                "height_px": f.grid.shape[0],
                "film_area_mm2": film_area_mm2(f.flat),
                "material": {"name": f.material.name, "max_stretch": f.material.max_stretch},
                "stretch": {"min": float(q[0]), "p50": float(q[1]), "max": float(q[2])},
                "within_material_share": f.within,
                "seam_mm": seam["per_film_mm"][k],
                "atlas_px": [int(f.atlas_px[0]), int(f.atlas_px[1])],
                "atlas_faces": [int(f.atlas_faces[0]), int(f.atlas_faces[1])],
                "scale_mode": str(f.flat.scale),
            }
        )
    return records


# regions outside the material's band listed in design.json (the largest; the rest counted)
MAX_OUTSIDE_REGIONS = 10


def within_material(result, limit: float | None, stated: float | None = None) -> dict | None:
    """design.json's ``within_material``: the share of the surface the films keep within the material's band,
    and where the rest lies.

    Parameters
    ----------
    result : DesignResult
        The design (its films, or its one map).
    limit : float or None
        The material's max_stretch (3D length / print length) of a design of one film.
    stated : float, optional
        The share ``films = "auto"`` was asked to keep (``[object].material.within_share``).

    Returns
    -------
    dict or None
        ``band``, ``share`` (0 to 1), ``stated_share``, ``outside_mm2`` (surface mm²) and
        ``regions``, the largest regions outside the band (film, area mm², centre mm on the
        part, the stretch farthest outside, which side); None without a material limit.
    """
    pieces = (
        [(f.name, f.flat, f.material.max_stretch) for f in result.films]
        if result.films
        else [("film-1", result.flat, limit)]
    )
    if any(m is None for _, _, m in pieces):
        return None
    total = inside = 0.0
    found = []
    for name, flat, m in pieces:
        ok = ~flat.collapsed
        labels, figures = outside_band(flat.V, flat.F, flat.stretch, flat.area_3d, ok, m)
        total += float(flat.area_3d[ok].sum())
        inside += float(flat.area_3d[ok & (labels < 0)].sum())
        found += [(name, m, row) for row in figures]
    found.sort(key=lambda r: -r[2][0])
    return {
        "band": [MIN_STRETCH, max(m for _, _, m in pieces)],
        "share": inside / total if total else 1.0,
        **({"stated_share": stated} if stated is not None else {}),
        "outside_mm2": total - inside,
        "regions": [
            {
                "film": name,
                "area_mm2": round(float(row[0]), 2),
                "centre_mm": [round(float(v), 2) for v in row[1:4]],
                "stretch": round(float(row[4]), 3),
                "beyond": "max_stretch" if row[4] > m else "min_stretch",
            }
            for name, m, row in found[:MAX_OUTSIDE_REGIONS]
        ],
        "regions_not_listed": max(len(found) - MAX_OUTSIDE_REGIONS, 0),
        "note": (
            "the share of the surface whose stretch (3D length / print length) lies within the band "
            f'[{MIN_STRETCH:g}, max_stretch]; films = "auto" makes the fewest films it finds that keep '
            "stated_share ([object].material.within_share) of it there. Regions: the connected parts of the "
            "surface outside the band, largest first: their film, area, centre on the part (mm, area-weighted) "
            "and the stretch farthest outside the band"
        ),
    }


def within_material_line(plan: dict) -> str:
    """The design log's line of :func:`within_material`."""
    lo, hi = plan["band"]
    words = f"{100 * plan['share']:.2f} % of the surface within the material's band [{lo:g}, {hi:g}]"
    if not plan["regions"]:
        return words
    r = plan["regions"][0]
    n = len(plan["regions"]) + plan["regions_not_listed"]
    x, y, z = r["centre_mm"]
    return (
        f"{words}; the rest, {plan['outside_mm2']:.1f} mm², in {n} region{'s' if n != 1 else ''}, the largest "
        f"{r['area_mm2']:.1f} mm² on {r['film']} at ({x:.1f}, {y:.1f}, {z:.1f}) mm (stretch {r['stretch']:.2f})"
    )


def base_print(comp, px_per_mm: float) -> dict:
    """The uncompensated print a compensation started from (what the profile's field is defined on)."""
    return {
        "width_mm": comp.base[0],
        "height_mm": comp.base[1],
        "width_px": int(np.ceil(comp.base[0] * px_per_mm - 1e-9)),
        "height_px": int(np.ceil(comp.base[1] * px_per_mm - 1e-9)),
    }


def moved_summary(moved: np.ndarray) -> dict:
    return {"median": float(np.median(moved)), "p95": float(np.percentile(moved, 95)), "max": float(moved.max())}


def print_with_alpha(rgb: np.ndarray, film: np.ndarray) -> np.ndarray:
    """The print as RGB when the film is the whole rectangle, else RGBA, transparent outside the film."""
    return rgb if film.all() else np.dstack([rgb, np.where(film, 255, 0).astype(np.uint8)])


def run(args) -> int:
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    job = load_job(args.job)
    out = Path(args.out) if args.out else Path(f"design-{safe_name(job.name)}")
    profile = Path(args.forming_profile) if args.forming_profile else job.object.forming_profile
    inputs = [job.path, job.object.mesh, *(v.image for v in job.views), *(v.mask for v in job.views if v.mask)]
    inputs += [profile] if profile else []
    check_output_dir(out, inputs)  # before the minutes of work, not after them
    result = design(job, log, profile)
    warnings = fit_warnings(result, job.object.material.max_stretch, [v.name for v in job.views])
    if warnings and args.strict:
        raise WorkbenchError(f"{job.path}: the print does not fit the part (--strict): " + "; ".join(warnings))

    t0 = time.perf_counter()
    names = [v.name for v in job.views]
    grid, flat = result.grid, result.flat
    rows, cols = grid.shape
    image_w_mm, image_h_mm = cols / grid.px_per_mm, rows / grid.px_per_mm
    vt = texture_uv(flat.uv, image_w_mm, image_h_mm, flat.height_mm)
    vt_films = vt
    if result.films:
        # viewers: each film's faces use that film's own print (vt into it)
        vt_films, groups = vt.copy(), []
        for k, f in enumerate(result.films):
            lo, hi = f.atlas_faces
            verts = np.unique(result.F[lo:hi])
            fr, fc = f.grid.shape
            ppm = grid.px_per_mm
            local = flat.uv[verts] - [f.atlas_px[1] / ppm, flat.height_mm - f.atlas_px[0] / ppm - f.flat.height_mm]
            vt_films[verts] = texture_uv(local, fc / grid.px_per_mm, fr / grid.px_per_mm, f.flat.height_mm)
            groups.append((f"film-{k + 1}", f"print-{f.name}.png", lo, hi))
        obj, mtl = decorated_obj(result.V, result.F, vt_films, "decorated", "print.png", groups)
    else:
        obj, mtl = decorated_obj(result.V, result.F, vt, "decorated", "print.png")
    stats = view_statistics(result, names)
    flat_summary = summary(flat)
    limit = job.object.material.max_stretch
    over = None if limit is None else float(flat.area_3d[~flat.collapsed][flat.stretch[~flat.collapsed] > limit].sum())
    plan = within_material(result, limit, job.object.material.within_share if job.films == "auto" else None)
    # the mesh and the view images, each read once for its hash and (an image) its orientation
    recorded = (job.object.mesh, *(v.image for v in job.views))
    contents = [p.read_bytes() for p in recorded]
    info = {
        "software": {"name": "workbench", "version": __version__},
        # paths relative to the design folder, each with its hash: the folder travels
        "job": {"file": recorded_path(job.path, out), "sha256": job.sha256, "name": job.name},
        "inputs": [
            {"file": recorded_path(p, out), "sha256": hashlib.sha256(data).hexdigest()}
            for p, data in zip(recorded, contents, strict=True)
        ],
        # each view image as it was used: turned upright by its EXIF orientation (1: as stored)
        "view_image_orientation": [exif_orientation(data) for data in contents[1:]],
        "print": {
            "width_mm": flat.width_mm,
            "height_mm": flat.height_mm,
            "dpi": grid.dpi,
            "width_px": cols,
            "height_px": rows,
            "image_width_mm": image_w_mm,
            "bleed_mm": job.print.bleed_mm,
            "margin_mm": job.print.margin_mm,
            "image_height_mm": image_h_mm,
            "background_share": background_share(result),
            "outline": job.print.outline,
            "film_area_mm2": film_area_mm2(flat),
            "film_share": float(result.film.mean()),
        },
        "corners": flat_summary["corners"],
        "corner_rule": flat_summary["corner_rule"],
        "scale_mode": flat_summary["scale_mode"],
        "material": {"name": job.object.material.name, "max_stretch": limit, "surface_over_limit_mm2": over},
        "stretch": flat_summary["stretch"],
        "conformal_distortion": flat_summary["conformal_distortion"],
        "flatten": {
            k: flat_summary[k]
            for k in (
                "angle_residual_max_rad",
                "newton_iterations",
                "flipped_faces",
                "collapsed_faces",
                "intrinsic_flips",
            )
        },
        "warnings": warnings,
        # the surface no view owns (faces no view claims): what `workbench suggest-views` proposes views for
        "undecorated_mm2": result.undecorated[0],
        "undecorated_share": result.undecorated[1],
        **({"within_material": plan} if plan is not None else {}),
        "views": stats,
        "mesh": {**flat_summary["mesh"], "surface_area_mm2": float(flat.area_3d.sum())},
    }
    if result.surface is not None:
        # what of the part is printed and why: the views' surface, margin, holes, islands, seams
        info["surface"] = result.surface
    comps = [f.compensation for f in result.films] if result.films else [result.compensation]
    comp = comps[0]
    if comp is not None:
        # the profile travels with the design (render, validate and a second round read it)
        data = Path(comp.profile).read_bytes()
        files_forming = {out / "forming-profile.json": data}
        moved = np.concatenate([c.moved_mm for c in comps])
        if not result.films:
            info["print"]["frame_offset_px"] = list(comp.frame_offset_px)
        info["forming"] = {
            "profile": {
                "file": "forming-profile.json",
                "sha256": hashlib.sha256(data).hexdigest(),
                "source": recorded_path(Path(comp.profile), out),
            },
            "round": comp.round,
            "moved_mm": moved_summary(moved),
            "note": "each print pixel p shows the surface point where the profile says p lands: the design's map "
            "composed with the profile; the uncompensated print's pixel (i, j) is this print's "
            "(i + frame_offset_px[1], j + frame_offset_px[0])"
            + ("; with several films, each film's own print and its films[k].forming" if result.films else ""),
        }
        if not result.films:
            info["forming"].update(
                base_print=base_print(comp, grid.px_per_mm), frame_offset_px=list(comp.frame_offset_px)
            )
    else:
        files_forming = {}
    # with several films, each film's name at its centre on views.png and stretch.png
    labels = []
    for k, f in enumerate(result.films):
        lo, hi = f.atlas_faces
        pts = flat.uv[np.unique(result.F[lo:hi])]
        # the film's point nearest its centroid: on the film even for a ring
        c = pts[np.argmin(np.linalg.norm(pts - pts.mean(axis=0), axis=1))]
        # (the flat layout counts y up; the pictures, as the print, down from its top edge)
        labels.append((float(c[0]), float(flat.height_mm - c[1]), f"{k + 1}" if len(result.films) > 9 else f.name))
    files = {
        # outside a free outline there is no film: transparent, in the background colour
        out / "print.png": png_bytes(print_with_alpha(result.rgb, result.film), grid.dpi),
        # owning view + 1 per print pixel (0: none), read by validate
        out / "owner.png": png_bytes((result.owner.astype(np.int16) + 1).astype(np.uint8), grid.dpi),
        out / "decorated.obj": obj,
        out / "decorated.mtl": mtl,
        out / "decorated.glb": decorated_glb(
            result.V,
            result.F,
            vt_films if result.films else vt,
            result.rgb,
            parts=[(f.name, *f.atlas_faces, f.rgb) for f in result.films] or None,
        ),
        out / "flat.obj": format_obj(
            np.column_stack([flat.uv, np.zeros(len(flat.uv))]),
            result.F,
            header=f"workbench {__version__} flat layout of {job.object.mesh.name}, mm",
        ),
        out / "views.png": views_figure(
            result.owner,
            names,
            [s["print_share"] for s in stats],
            flat.width_mm,
            flat.height_mm,
            f"{job.name}: which view owns each print pixel"
            + ("" if result.surface is None else "\n" + "\n".join(textwrap.wrap(surface_line(result.surface), 95))),
            film=None if result.film.all() else result.film,
            labels=labels,
        ),
        out / "stretch.png": stretch_figure(
            flat.uv,
            result.F,
            flat.stretch,
            flat.corners,
            flat.width_mm,
            flat.height_mm,
            title=f"{job.name}: film stretch, {job.object.material.name}"
            + "".join("\n" + "\n".join(textwrap.wrap(f"warning: {w}", 95)) for w in warnings),
            limit=limit,
            labels=labels,
        ),
    }
    files.update(files_forming)
    if result.surface_picture is not None:
        files[out / "surface.png"] = result.surface_picture
    if result.films:
        info["films"] = film_records(result)
        for rec, f in zip(info["films"], result.films, strict=True):
            if f.compensation is not None:
                # each film's print grew on its own: where its uncompensated print's corner went
                rec["forming"] = {
                    "base_print": base_print(f.compensation, grid.px_per_mm),
                    "frame_offset_px": list(f.compensation.frame_offset_px),
                    "moved_mm": moved_summary(f.compensation.moved_mm),
                }
        info["seams"] = {"length_mm": result.seams["length_mm"], "inside_a_view_mm": result.seams["in_view_mm"]}
        for f in result.films:
            files[out / f"print-{f.name}.png"] = png_bytes(print_with_alpha(f.rgb, f.film), grid.dpi)
            files[out / f"flat-{f.name}.obj"] = format_obj(
                np.column_stack([f.flat.uv, np.zeros(len(f.flat.uv))]),
                f.flat.F,
                header=f"workbench {__version__} flat layout of film {f.name} of {job.object.mesh.name}, mm",
            )
    # the view images, so that the design directory alone is enough to validate photos
    # (as the design read them: an RGBA image over the print's background, 8 bits)
    for i, v in enumerate(job.views):
        png = v.image.read_bytes() if v.image.suffix.lower() == ".png" else b""
        plain = png[25:26] in (b"\x00", b"\x02") and png[24:25] == b"\x08"  # IHDR: 8-bit grey or RGB, no alpha
        files[out / f"view-{safe_name(v.name)}.png"] = (
            png if plain else png_bytes(read_image(v.image, f"{job.path}: views[{i}].image", job.print.background))
        )
    spec, origin, footprint = fixture_from_job(job.fixture, result.V, result.F, f"{job.path}: fixture")
    extra = {"job": info["job"], "footprint_board_mm": footprint.tolist()}
    chart = colour_chart_from_job(job.fixture, spec, origin)
    if chart is not None:  # the colour chart's slot beside the board: validate's colour QA reads it
        extra["colour_chart"] = chart
    fixture = definition(spec, "fixture", origin_mm=origin, extra=extra)
    files[out / "fixture.json"] = (json.dumps(fixture, indent=1) + "\n").encode()
    timings = {**result.timings_s, "write": time.perf_counter() - t0}
    info["timings_s"] = {k: round(v, 4) for k, v in timings.items()}
    files[out / "design.json"] = (json.dumps(info, indent=2) + "\n").encode()
    write_folder(out, files, inputs)
    log(
        f"print {flat.width_mm:.2f} x {flat.height_mm:.2f} mm, {cols} x {rows} px at {grid.dpi:g} dpi; "
        + "; ".join(f"{s['name']} {100 * s['print_share']:.1f} %" for s in stats)
        + f"; background {100 * info['print']['background_share']:.1f} %"
    )
    if result.surface is not None:
        log(surface_line(result.surface))
    left_mm2, left_share = result.undecorated
    log(
        f"undecorated: {100 * left_share:.1f} % of the surface ({left_mm2:.0f} mm²) no view owns"
        + (f"; `workbench suggest-views {args.job}` proposes views for it" if left_mm2 > 0 else "")
    )
    if plan is not None:
        log(within_material_line(plan))
    if over:
        log(f"warning: {over:.1f} mm² of the surface stretch beyond the material's limit {limit:g}")
    for w in warnings:
        log(f"warning: {w}")
    log(
        f"wrote {out}/: print.png, decorated.obj/.mtl/.glb, flat.obj, design.json, views.png, stretch.png, fixture.json"
    )
    return 0

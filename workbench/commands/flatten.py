"""``workbench flatten``: conformal map of a mesh onto a rectangle, written as flat.obj + flatten.json."""

from __future__ import annotations

import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

from workbench import __version__
from workbench.atomic import check_output_dir, write_folder
from workbench.conformal.distortion import weighted_quantiles
from workbench.conformal.flatten import (
    CrowdingError,
    FlattenOptions,
    FlattenResult,
    ScaleMode,
    crowding_advice,
    flatten,
    flatten_auto_corners,
)
from workbench.errors import UsageError
from workbench.figures import stretch_figure
from workbench.jsonfile import recorded_path
from workbench.mesh.io import UNITS_MM, MeshName, format_obj, read_mesh
from workbench.options import Number, parse_numbers


def add_parser(sub) -> None:
    p = sub.add_parser(
        "flatten",
        help="map a disc-shaped mesh conformally onto a rectangle (CETM)",
        description=(
            "Map a disc-shaped mesh conformally onto a rectangle at physical scale "
            "(Springborn, Schröder, Pinkall 2008; intrinsic Delaunay flips after Gillespie, Springborn, "
            "Crane 2021 where the mesh needs them). Writes DIR/flat.obj (z = 0, mm, corner A at the origin, "
            "A→B along +x; the input's vertices first in their order, then, where edges were flipped, the "
            "vertices of the common subdivision), DIR/flatten.json and DIR/flatten.png (film stretch)."
        ),
    )
    p.add_argument(
        "mesh",
        metavar="MESH",
        help="OBJ, PLY, STL, OFF or GLB file; faces counter-clockwise seen from the decorated side",
    )
    p.add_argument(
        "--corners",
        metavar="A,B,C,D",
        help="four boundary vertex indices (0-based), counter-clockwise; or 'auto': compare several corner "
        "choices and keep the one that prints every face with the least area distortion; "
        "default: the sharpest boundary turns (else the bounding box)",
    )
    p.add_argument(
        "--scale",
        default=None,
        metavar="MODE",
        help="isometric (default for a rectangle), area (the film's area equals the surface's; default for a free "
        "outline), no-shrink, width=MM, height=MM, or rim (free outline: keep the rim's lengths)",
    )
    p.add_argument(
        "--outline",
        default="rectangle",
        choices=("rectangle", "free"),
        help="rectangle (default; four corners) or free (least area distortion: the film keeps the rim's lengths, "
        "the outline follows)",
    )
    p.add_argument(
        "--units", default="mm", choices=sorted(UNITS_MM), help="unit of the mesh file's coordinates (default mm)"
    )
    p.add_argument(
        "--dpi",
        action=Number,
        lo=1,
        hi=10000,
        default=300.0,
        help="print resolution the map must serve: a face printed below half a pixel is crowded (default 300)",
    )
    p.add_argument("--out", metavar="DIR", help="output directory (default: flatten-<mesh name>)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


def parse_corners(text: str | None) -> tuple[int, int, int, int] | None:
    """``'A,B,C,D'`` → four ints; None stays None."""
    if text is None or text == "auto":
        return None
    if len(text.split(",")) != 4:
        raise UsageError(f"--corners {text!r}: give four vertex indices, e.g. --corners 0,99,9999,9900")
    # an index beyond any mesh (2**31) cannot be a vertex; the mesh's own count is checked once it is read
    return parse_numbers(text, 4, "--corners", lo=0, hi=2**31 - 1, integer=True)  # type: ignore[return-value]


def summary(result: FlattenResult) -> dict:
    """The figures of flatten.json (everything but inputs and timings)."""
    ok = ~result.collapsed
    stretch, dist, w = result.stretch[ok], result.conformal_distortion[ok], result.area_3d[ok]
    p50, p95 = weighted_quantiles(stretch, w, [0.5, 0.95])
    return {
        "corners": [int(c) for c in result.corners],
        "corner_rule": result.corner_rule,
        "width_mm": result.width_mm,
        "height_mm": result.height_mm,
        "scale_mode": str(result.scale),
        "angle_residual_max_rad": result.newton.residual_rad,
        "newton_iterations": result.newton.iterations,
        "newton_residual_history_rad": result.newton.history,
        "flipped_faces": result.flipped_faces,
        "collapsed_faces": {
            "count": int(result.collapsed.sum()),
            "area_mm2": float(result.area_3d[result.collapsed].sum()),
        },
        "intrinsic_flips": result.intrinsic_flips,
        "rectangle_side_mismatch": result.rectangle_mismatch,
        "stretch": {
            "min": float(stretch.min()),
            "p50": float(p50),
            "p95": float(p95),
            "max": float(stretch.max()),
            "weighting": "surface area",
        },
        "conformal_distortion": {"mean": float(np.average(dist, weights=w)), "max": float(dist.max())},
        "surface_area_mm2": float(w.sum()),
        "print_area_mm2": result.width_mm * result.height_mm,
        # every input face has at least one output face: the input's face count is the parent range
        "mesh": {"vertices": result.n_input_vertices, "faces": int(result.parent.max()) + 1},
        # flat.obj's triangulation: the input's, or its common subdivision with the flat
        # triangulation when the solve flipped edges (input vertices first, in order)
        "output_mesh": {"vertices": len(result.V), "faces": len(result.F)},
    }


def run(args) -> int:
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    corners = parse_corners(args.corners)
    scale = ScaleMode.parse(args.scale) if args.scale is not None else ScaleMode.default(args.outline)
    mesh_path = Path(args.mesh)
    out = Path(args.out) if args.out else Path(f"flatten-{mesh_path.stem}")

    if args.outline == "free" and args.corners is not None:
        raise UsageError("--corners belongs to --outline rectangle; a free outline has no corners")
    check_output_dir(out, inputs=[mesh_path])  # before the work, not after it
    t0 = time.perf_counter()
    V, F = read_mesh(mesh_path, args.units, log=log)
    t_read = time.perf_counter() - t0
    log(f"read {mesh_path}: {len(V)} vertices, {len(F)} faces ({t_read:.2f} s)")
    compared = None
    options = FlattenOptions(
        corners=corners,
        scale=scale,
        min_print_mm=0.5 * 25.4 / args.dpi,
        outline=args.outline,
        corners_from=f"{mesh_path}: --corners",
    )
    if args.corners == "auto":
        result, compared = flatten_auto_corners(V, F, options, name=MeshName(mesh_path), log=log)
    else:
        try:
            result = flatten(V, F, options, name=MeshName(mesh_path), log=log)
        except CrowdingError as exc:
            raise crowding_advice(exc, V, F, options, str(mesh_path), log) from None

    t0 = time.perf_counter()
    info = {
        "software": {"name": "workbench", "version": __version__},
        "input": {
            "mesh": recorded_path(mesh_path, out),
            "sha256": hashlib.sha256(mesh_path.read_bytes()).hexdigest(),
            "units": args.units,
        },
        **summary(result),
    }
    if compared is not None:
        info["corner_search"] = compared
    flat = np.column_stack([result.uv, np.zeros(len(result.uv))])
    obj = format_obj(
        flat,
        result.F,
        header=f"workbench {__version__} flatten of {mesh_path.name}\nmm, corner A at the origin, A->B along +x",
    )
    png = stretch_figure(
        result.uv,
        result.F,
        result.stretch,
        result.corners,
        result.width_mm,
        result.height_mm,
        title=f"{mesh_path.name}: {result.width_mm:.2f} x {result.height_mm:.2f} mm, scale {result.scale}",
    )
    t_write = time.perf_counter() - t0
    timings = {"read": t_read, **result.timings_s, "write": t_write}
    # timings are the one field that differs between two runs on the same input
    info["timings_s"] = {k: round(v, 4) for k, v in timings.items()}
    write_folder(
        out,
        {
            out / "flat.obj": obj,
            out / "flatten.json": (json.dumps(info, indent=2) + "\n").encode(),
            out / "flatten.png": png,
        },
        inputs=[mesh_path],
    )
    log(
        f"{result.width_mm:.3f} x {result.height_mm:.3f} mm ({result.scale}); "
        f"{result.newton.iterations} Newton steps, residual {result.newton.residual_rad:.1e} rad; "
        f"stretch {info['stretch']['min']:.4f}..{info['stretch']['max']:.4f}; flipped faces {result.flipped_faces}"
    )
    log(f"wrote {out / 'flat.obj'}, {out / 'flatten.json'}, {out / 'flatten.png'}")
    return 0

"""``workbench suggest-views``: which view next, for the surface no view of the job owns yet."""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np

from workbench import __version__
from workbench.atomic import check_outputs, write_files
from workbench.design import _read_faces
from workbench.errors import UsageError, WorkbenchError
from workbench.job import load_job
from workbench.job_views import assign_job_views, read_view_images
from workbench.mesh.io import read_mesh
from workbench.options import Number, parse_numbers
from workbench.text import ascii_text
from workbench.views.suggest import (
    Coverage,
    Remaining,
    SuggestOptions,
    elevation_deg,
    remaining_surface,
    suggest_views,
    template_image,
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "suggest-views",
        help="propose ranked viewpoints for the surface no view of the job owns yet",
        description=(
            "From the job's views (priority order, the same visibility and one-region rules as design), find the "
            "surface no view owns and propose N distinct viewpoints, best first, each covering as much of it as "
            "possible at a good angle. Each is a ready [[views]] table of the job (name, image, position, "
            "look_at, up, fov_deg, width_px, height_px for the print's dpi) with covers_share and covers_mm2. "
            "Without -o the tables go to stdout; -o FILE.toml writes them, an image template per suggestion "
            "beside it (NAME.png: the view's outline of the part and the region it would own; one that exists "
            "with other content, a picture drawn on it, is never replaced) and FILE-views.png "
            "(the part with what each suggestion would own)."
        ),
    )
    p.add_argument("job", metavar="JOB.toml", help="job file (see README: Job file)")
    p.add_argument(
        "-n", action=Number, lo=1, hi=20, integer=True, default=3, metavar="N", help="how many suggestions (default 3)"
    )
    p.add_argument("-o", "--output", metavar="FILE.toml", help="write the suggestions, templates and picture")
    p.add_argument(
        "--distance-mm",
        metavar="D|LO,HI",
        help="camera distance from the part's centre, or a range searched (default: the job's cameras' median)",
    )
    p.add_argument(
        "--min-elevation-deg",
        action=Number,
        lo=-90,
        hi=90,
        default=-90.0,
        help="lowest camera elevation above the plane normal to --up, degrees (default -90: anywhere)",
    )
    p.add_argument(
        "--up",
        metavar="X,Y,Z",
        help="the direction towards the top of every image, and the elevation's zenith (default: the fixture plate's "
        "normal, +z of the mesh: the plate lies under the part, so a camera overhead is at elevation 90°)",
    )
    p.add_argument(
        "--fov-deg",
        action=Number,
        lo=0,
        hi=180,
        lo_open=True,
        hi_open=True,
        help="horizontal field of view (default: the whole part in the frame)",
    )
    p.add_argument("--size", metavar="WxH", help="image size in px (default: what the print's dpi needs)")
    p.add_argument(
        "--max-obliquity-deg",
        action=Number,
        lo=0,
        hi=90,
        default=60.0,
        help="surface seen more obliquely than this does not count towards the score (default 60)",
    )
    p.add_argument(
        "--min-separation-deg",
        action=Number,
        lo=0,
        hi=180,
        default=20.0,
        help="least angle between two suggestions' viewing directions (default 20)",
    )
    p.add_argument("--favour", metavar="FACES.txt", help="0-based face indices that count twice")
    p.add_argument("--avoid", metavar="FACES.txt", help="0-based face indices a suggestion should not own")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


# the fixture's plate lies in the mesh's x-y plane, under the part (board fixture: mesh = origin + (x, -y, 0))
PLATE_NORMAL = (0.0, 0.0, 1.0)


def _numbers(flag: str, text: str, counts: tuple[int, ...]) -> list[float]:
    n = len(text.split(","))
    if n not in counts:
        raise UsageError(f"{flag} {text!r}: give {' or '.join(map(str, counts))} comma-separated numbers")
    # lengths and directions beyond a million (mm) are no camera's: their products overflow
    return list(parse_numbers(text, n, flag, lo=-1e6, hi=1e6))


def options_from_args(args) -> SuggestOptions:
    """The command line's constraints, each checked (exit 2 when out of range)."""
    if not 1 <= args.n <= 20:
        raise UsageError(f"-n {args.n}: give 1 to 20 suggestions")
    distance = None
    if args.distance_mm is not None:
        d = _numbers("--distance-mm", args.distance_mm, (1, 2))
        lo, hi = d[0], d[-1]
        if not 0 < lo <= hi:
            raise UsageError(f"--distance-mm {args.distance_mm!r}: give D > 0, or LO,HI with 0 < LO <= HI")
        distance = (lo, hi)
    up = PLATE_NORMAL  # (the job's views may look any way: the first one's image up is no zenith)
    if args.up is not None:
        up = _numbers("--up", args.up, (3,))
        if np.linalg.norm(up) == 0:
            raise UsageError(f"--up {args.up!r}: a direction cannot be zero")
        up = tuple(up)
    if args.fov_deg is not None and not 0 < args.fov_deg < 180:
        raise UsageError(f"--fov-deg {args.fov_deg:g}: must be between 0 and 180")
    size = None
    if args.size is not None:
        try:
            w, h = (int(x) for x in args.size.lower().split("x"))
        except ValueError:
            raise UsageError(f"--size {args.size!r}: give WxH in pixels, e.g. 1600x1200") from None
        if not (8 <= w <= 16384 and 8 <= h <= 16384):
            raise UsageError(f"--size {args.size!r}: each side must be 8 to 16384 px")
        size = (w, h)
    for flag, value, lo, hi in (
        ("--min-elevation-deg", args.min_elevation_deg, -90, 90),
        ("--max-obliquity-deg", args.max_obliquity_deg, 0, 90),
        ("--min-separation-deg", args.min_separation_deg, 0, 180),
    ):
        if not (math.isfinite(value) and lo <= value <= hi):
            raise UsageError(f"{flag} {value:g}: must be between {lo} and {hi}")
    return SuggestOptions(
        count=args.n,
        distance_mm=distance,
        min_elevation_deg=args.min_elevation_deg,
        up=up,
        fov_deg=args.fov_deg,
        size_px=size,
        max_obliquity_deg=args.max_obliquity_deg,
        min_separation_deg=args.min_separation_deg,
    )


def _vec(x) -> str:
    return "[" + ", ".join(repr(float(v) + 0.0) for v in x) + "]"


def view_tables(job, rem: Remaining, suggestions: list[Coverage], names: list[str], images: list[str], options) -> str:
    """The suggestions as the job file's own ``[[views]]`` tables, best first."""
    left = rem.undecorated_mm2
    share = left / float(rem.area.sum())
    lines = [
        f"# workbench {__version__} suggest-views for {job.path.name} (sha256 {job.sha256[:16]}...)",
        f"# the job's {len(job.views)} views leave {100 * share:.1f} % of the surface ({left:.0f} mm²) undecorated.",
        "# Each table below is a ready [[views]] table of that job, best first: appended after the job's views,",
        "# it owns covers_share of the undecorated surface (covers_mm2), as design will report it. The",
        f"# suggestions are alternatives, each scored alone, at least {options.min_separation_deg:g}° apart;",
        f"# the score counts the surface seen within {options.max_obliquity_deg:g}° of face on.",
        "# image: a template of the view (the part's outline, the region it would own), path relative to the",
        "# job file: draw the view's picture on it, at its size (width_px x height_px suits the print's dpi).",
    ]
    if not suggestions:
        lines.append("# nothing to suggest: " + ("no surface is left" if left <= 0 else "no direction owns any of it"))
    for cov, name, image in zip(suggestions, names, images, strict=True):
        cam = cov.camera
        elevation = float(elevation_deg(rem, cov.direction[None])[0])
        lines += [
            "",
            "[[views]]",
            f'name = "{name}"',
            f'image = "{image}"',
            f"position = {_vec(cov.position)}",
            f"look_at = {_vec(cov.look_at)}",
            f"up = {_vec(cov.up)}",
            f"fov_deg = {round(rem.fov_deg, 6)!r}",
            f"width_px = {cam.width}",
            f"height_px = {cam.height}",
            f"covers_share = {round(cov.covers_mm2 / left, 4)!r}",
            f"covers_mm2 = {round(cov.covers_mm2, 1)!r}",
            f"# within {options.max_obliquity_deg:g}° of face on: {cov.good_mm2:.0f} mm²; "
            f"{cov.distance_mm:.0f} mm from the part's centre, elevation {elevation:.1f}°",
        ]
    return "\n".join(lines) + "\n"


# each suggestion's colour in the picture
PALETTE = np.array([[0.12, 0.47, 0.71], [0.17, 0.63, 0.17], [0.58, 0.40, 0.74], [1.0, 0.5, 0.05], [0.09, 0.75, 0.81]])


def suggestions_figure(
    rem: Remaining, suggestions: list[Coverage], names: list[str], first_camera, title: str
) -> bytes:
    """The part from each suggestion's camera, with what it would own, and from the job's first view.

    Drawn with OpenCV, not matplotlib: importing pyplot alone took 1 to 2 s of a command that
    should answer in a few (and the picture needs no axes).
    """
    import cv2

    from workbench.export import png_bytes
    from workbench.raster import depth_buffer

    side = 480
    # owned: grey; undecorated: red
    base = np.where(rem.claimed[:, None], [[0.78, 0.78, 0.78]], [[0.86, 0.30, 0.30]])
    panels = [(first_camera, None, "the job's first view: every suggestion")] + [
        (c.camera, k, f"{names[k]}: {100 * c.covers_mm2 / rem.undecorated_mm2:.1f} % ({c.covers_mm2:.0f} mm2)")
        for k, c in enumerate(suggestions)
    ]
    tiles = []
    for cam, k, label in panels:
        small = cam.scaled(min(1.0, side / max(cam.width, cam.height)))
        xy, z = small.project(rem.V)
        fb, _ = depth_buffer(xy, z, rem.F, small.width, small.height)
        col = base.copy()
        for j, c in reversed(list(enumerate(suggestions))):
            if k is None or k == j:
                col[c.new] = PALETTE[j % len(PALETTE)]
        sight = small.center - rem.centroid
        shade = np.abs(np.einsum("ij,ij->i", rem.normal, sight)) / np.linalg.norm(sight, axis=1)
        img = np.ones((small.height, small.width, 3))
        seen = fb >= 0
        img[seen] = col[fb[seen]] * (0.35 + 0.65 * shade[fb[seen], None])
        tile = np.full((side + 40, side, 3), 255, np.uint8)
        h, w = min(small.height, side), min(small.width, side)
        r0, c0 = 40 + (side - h) // 2, (side - w) // 2
        tile[r0 : r0 + h, c0 : c0 + w] = np.round(255 * img[:h, :w]).astype(np.uint8)
        cv2.putText(tile, ascii_text(label), (8, 26), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        tiles.append(tile)
    body = np.concatenate(tiles, axis=1)
    head = np.full((56, body.shape[1], 3), 255, np.uint8)
    legend = "grey: owned by the job's views; red: undecorated; colour: what a suggestion would own"
    for row, text in ((22, title), (46, legend)):
        cv2.putText(head, ascii_text(text), (8, row), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    return png_bytes(np.concatenate([head, body], axis=0))


def run(args) -> int:
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    options = options_from_args(args)
    job = load_job(args.job)
    out = Path(args.output) if args.output else None
    inputs = [job.path, job.object.mesh, *(v.image for v in job.views), *(v.mask for v in job.views if v.mask)]
    inputs += [Path(p) for p in (args.favour, args.avoid) if p]
    if out is not None:
        check_outputs(out, out.with_name(f"{out.stem}-views.png"), inputs=inputs)
    V, F = read_mesh(job.object.mesh, job.object.units, log=log)
    images, decorations = read_view_images(job)
    favour = avoid = None
    for flag, value in (("--favour", args.favour), ("--avoid", args.avoid)):
        if value is not None:
            path = Path(value)
            if not path.is_file():
                raise UsageError(f"{flag} {value}: no such file")
            mask = np.zeros(len(F), bool)
            mask[_read_faces(path, len(F), flag)] = True
            favour, avoid = (mask, avoid) if flag == "--favour" else (favour, mask)
    cameras, _, status = assign_job_views(job, V, F, images, decorations)
    rem = remaining_surface(V, F, status, cameras, job.print.dpi, options, favour, avoid)
    share = rem.undecorated_mm2 / float(rem.area.sum())
    left = f"{100 * share:.1f} % of the surface ({rem.undecorated_mm2:.0f} mm²)"
    log(f"{job.path.name}: {len(job.views)} views leave {left} undecorated")
    suggestions = suggest_views(rem, options, log)

    taken = {v.name for v in job.views}
    names = []
    for k in range(len(suggestions)):
        name = f"suggest-{k + 1}"
        while name in taken:
            name += "-new"
        names.append(name)
    files = {}
    if out is not None:
        templates = [out.with_name(f"{name}.png") for name in names]
        check_outputs(*templates, inputs=inputs)
        rel = [os.path.relpath(os.path.realpath(p), job.path.parent) for p in templates]
    else:
        templates, rel = [], [f"{name}.png" for name in names]
    text = view_tables(job, rem, suggestions, names, rel, options)
    for k, cov in enumerate(suggestions):
        log(
            f"{k + 1}. {names[k]}: owns {100 * cov.covers_mm2 / rem.undecorated_mm2:.1f} % of the undecorated surface "
            f"({cov.covers_mm2:.0f} mm²; {cov.good_mm2:.0f} mm² within {options.max_obliquity_deg:g}°), "
            f"{cov.camera.width} x {cov.camera.height} px"
        )
    if out is None:
        try:
            sys.stdout.write(text)
            sys.stdout.flush()
        except BrokenPipeError:
            return 0  # the reader took what it wanted (``| head``)
        except OSError as exc:
            raise WorkbenchError(f"standard output: {exc.strerror or exc}; give -o FILE.toml") from None
        return 0
    from workbench.export import png_bytes

    files[out] = text.encode()
    for path, cov in zip(templates, suggestions, strict=True):
        files[path] = png_bytes(template_image(rem, cov))
        # a template is where the designer draws the view's picture: one that exists and is not
        # what this run writes (the same job gives the same bytes) may hold that drawing
        if path.exists() and path.read_bytes() != files[path]:
            raise WorkbenchError(
                f"{path}: exists and is not the template this run writes (a picture drawn on an earlier "
                "one?); move it away or give another -o; nothing written"
            )
    files[out.with_name(f"{out.stem}-views.png")] = suggestions_figure(
        rem, suggestions, names, cameras[0], f"{job.name}: {100 * share:.1f} % of the surface undecorated"
    )
    write_files(files, inputs=inputs)
    log(f"wrote {out}, {', '.join(p.name for p in templates)}{', ' if templates else ''}{out.stem}-views.png")
    return 0

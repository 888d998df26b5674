"""``workbench validate``: photos of the decorated part, posed on the fixture, scored against each view.

Argument handling, the worker pool and the output folder; the photo's pipeline is
:mod:`workbench.validate.photo`, the part's :mod:`workbench.validate.part`, the acceptance
rule :mod:`workbench.validate.rule`.
"""

from __future__ import annotations

import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import cv2
import numpy as np

from workbench import __version__, progress
from workbench.atomic import check_output_dir, check_outputs, safe_name, write_folder
from workbench.camera import load_camera_profile
from workbench.design_dir import Design, design_files
from workbench.errors import UsageError, WorkbenchError
from workbench.export import png_bytes
from workbench.jsonfile import recorded_path
from workbench.options import Number, parse_part_offset, parse_part_rotation
from workbench.validate import detection, landing, pictures
from workbench.validate.coverage import (
    MIN_COVERAGE,
    CoverageOptions,
    coverage_words,
    next_photo_line,
    next_photo_words,
    open_next_photo,
    part_coverage,
)
from workbench.validate.part import (
    add_found_together,
    decided_in_part,
    light_in_one_photo,
    open_told_elsewhere,
    part_summary,
)
from workbench.validate.part_colour import fused_colour, photo_names, take_colour_maps
from workbench.validate.photo import design_print_grid, print_grid_of, sha256, validate_photo
from workbench.validate.report import qa_report
from workbench.validate.report_html import interactive_report
from workbench.validate.rule import (
    MAX_DEFECT_MM2,
    MAX_DELTA_E,
    open_reason,
    photo_verdict,
    still_open,
    verdict_rule,
)
from workbench.validate.slide_fusion import FusionOptions, fused_part_limit, slides_found_together


def add_parser(sub) -> None:
    p = sub.add_parser(
        "validate",
        help="score photos of the decorated part against the designed views; QA report",
        description=(
            "For each photo: pose from the fixture's markers, the photo warped into the designed view through "
            "the mesh, misregistration (px in the view, mm on the surface), similarity, coverage, the film "
            "placement error that explains it, and a verdict (PASS, FAIL, INCOMPLETE or INVALID with the reason). "
            "Writes "
            "validation.json, per photo the warped photo, an overlay and a heat map, qa_report.pdf, and "
            "qa_report.html (one self-contained page: the part in 3D with its defects and coverage, its photos)."
        ),
    )
    p.add_argument("design", metavar="DESIGN_DIR")
    p.add_argument("photos", metavar="PHOTO", nargs="+")
    p.add_argument("--camera", metavar="PROFILE.json", required=True, help="camera profile: K, dist, image_size")
    p.add_argument("--view", metavar="NAME", help="compare with this view (default: the view nearest each photo)")
    p.add_argument(
        "--tolerance-mm",
        action=Number,
        lo=0,
        lo_open=True,
        hi=1000,
        unit="mm",
        default=0.5,
        help="largest accepted misregistration, p95 (default 0.5)",
    )
    p.add_argument(
        "--max-defect-mm2",
        action=Number,
        lo=0,
        lo_open=True,
        hi=1e6,
        unit="mm²",
        default=MAX_DEFECT_MM2,
        help=f"largest accepted local defect, area on the print in mm² (default {MAX_DEFECT_MM2:g})",
    )
    p.add_argument(
        "--max-delta-e",
        action=Number,
        lo=0,
        lo_open=True,
        hi=100,
        unit="ΔE00",
        default=MAX_DELTA_E,
        help="largest accepted mean colour difference (CIEDE2000) between the photo, corrected by the fixture's "
        f"colour chart, and the design's soft proof (default {MAX_DELTA_E:g})",
    )
    p.add_argument(
        "--output-profile",
        metavar="PROFILE.icc",
        help="the output ICC profile the print was made with (the one given to workbench pdf): the soft proof "
        "is the design's colours as that press prints them (default: the design's sRGB as it is)",
    )
    p.add_argument(
        "--seating",
        choices=("on", "off"),
        default="on",
        help="on (default): measure the part's own pose on its plate from its outline in each photo and judge the "
        "film on the part where it sits; off: the part is where the fixture puts it (a fixture that clamps it)",
    )
    p.add_argument(
        "--max-seating-mm",
        action=Number,
        lo=0,
        lo_open=True,
        hi=1000,
        unit="mm",
        default=2.0,
        help="a part whose centre sits farther than this from where the fixture puts it is a warning: it was not set "
        "in its outline (not a film fault; default 2)",
    )
    p.add_argument(
        "--part-rotation-deg",
        metavar="RX,RY,RZ",
        help="the fixture holds the part turned by RX, RY, RZ degrees about its centre (a stand that tilts it, so that "
        "photos see film the plate hides: a calibration film's rim); render's motion, R = Rz Ry Rx. The seating "
        "measures the part from there, with the stand's contact as its prior",
    )
    p.add_argument(
        "--part-offset-mm",
        metavar="X,Y[,Z]",
        help="... and its centre moved by X, Y, Z mm (mesh frame) from where the design puts it (default 0,0,0)",
    )
    p.add_argument(
        "--min-coverage",
        action=Number,
        lo=0,
        hi=1,
        default=MIN_COVERAGE,
        help=(
            "share of each film, per defect class (a slide beyond the tolerance, ink gone, a scratch), that the "
            "part's photos together must be able to find it on for a PASS; less is INCOMPLETE, with the "
            f"uncovered regions and the next photo to take (default {MIN_COVERAGE:g}; 0: coverage not required)"
        ),
    )
    p.add_argument(
        "--finish",
        choices=("glossy", "matte"),
        default="glossy",
        help="the film's surface. glossy (default): it may mirror a lamp, and a region a photo cannot tell ink gone "
        "from a glint on is open, decided by another photo from elsewhere (the part is INCOMPLETE until one does); "
        "matte: it adds no light of its own (the light on its ink scales the ink, texture and all), and such a "
        "region is ink gone",
    )
    p.add_argument(
        "--jobs",
        action=Number,
        lo=0,
        hi=1024,
        integer=True,
        default=0,
        help="photos scored in parallel, one process each (default: every core; 1: in this process)",
    )
    p.add_argument("--out", metavar="DIR", help="output directory (default: DESIGN_DIR/validation)")
    s = p.add_argument_group(
        "results store",
        "record the validation in a store once its outputs are written (nothing is recorded without one)",
    )
    s.add_argument(
        "--store",
        metavar="URL",
        help="the store: a SQLite file's path, or a SQLAlchemy URL (sqlite:///FILE, postgresql://...); "
        "default: $WORKBENCH_STORE, else no store",
    )
    s.add_argument("--part-id", metavar="ID", help="the part's id (required with a store)")
    s.add_argument("--lot", metavar="LOT", help="the lot the part belongs to (workbench lot decides on it)")
    s.add_argument("--station", metavar="NAME", help="the station recording (default: this machine's host name)")
    s.add_argument("--operator", metavar="NAME", help="who validates (default: the login name)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(run=run)


def store_recorder(args):
    """The store's :class:`~workbench.store.record.Recorder` (its URL checked), or None: no store.

    ``--part-id`` is required with a store (a record no part names counts in no lot); ``--part-id``,
    ``--lot``, ``--station`` and ``--operator`` without a store are refused rather than ignored.
    """
    from workbench.store.database import check_store, store_text, store_url

    text = store_text(args.store)
    if text is None:
        given = [o for o in ("part_id", "lot", "station", "operator") if getattr(args, o) is not None]
        if given:
            name = "--" + given[0].replace("_", "-")
            raise UsageError(f"{name}: records in a store; give --store URL (or set WORKBENCH_STORE)")
        return None
    from workbench.store.record import Recorder, default_operator, default_station

    option = "--store" if args.store is not None else "WORKBENCH_STORE"
    for name in ("part_id", "lot", "station", "operator"):
        value = getattr(args, name)
        if value is not None and not value.strip():
            raise UsageError(f"--{name.replace('_', '-')}: an empty name")
    if args.part_id is None:
        raise UsageError(f"--part-id: required to record in a store ({option} {text})")
    url = store_url(text, option)
    check_store(url, option)
    return Recorder(
        url=url,
        part_id=args.part_id,
        lot=args.lot,
        station=args.station or default_station(),
        operator=args.operator or default_operator(),
    )


def output_stems(photos: list[Path]) -> list[str]:
    """One distinct, safe file-name stem per photo, for its pictures in the output folder.

    The photo's own stem where it is unique; photos of one name from different folders
    get their folder's name in front, and what still collides its position in the list.
    Characters other than letters, digits, ``.``, ``_`` and ``-`` become ``_``, so that no
    name leaves the output folder.
    """
    own = [safe_name(p.stem) for p in photos]
    stems = [
        safe_name(f"{Path(os.path.realpath(p)).parent.name}_{p.stem}") if own.count(s) > 1 else s
        for p, s in zip(photos, own, strict=True)
    ]
    return [f"{s}-{k + 1}" if stems.count(s) > 1 else s for k, s in enumerate(stems)]


_WORKER: dict = {}


def _one_thread() -> None:
    # one process per core, each on one thread: with their own thread pools too, two photos
    # at once oversubscribe the cores (measured here: every stage two to three times slower)
    import numba

    cv2.setNumThreads(1)
    numba.set_num_threads(1)


def held_pose(args, design: Design) -> dict | None:
    """How the fixture holds the part (``--part-rotation-deg``, ``--part-offset-mm``), None when as designed.

    Returns render's ``part_pose`` of that motion (:func:`workbench.part_motion.motion_entry`):
    the design mesh's points are held at ``R X + t`` (mesh frame, mm).
    """
    from workbench.part_motion import motion_entry

    if args.part_rotation_deg is None and args.part_offset_mm is None:
        return None
    off = parse_part_offset(args.part_offset_mm) or (0.0, 0.0, 0.0)
    rot = parse_part_rotation(args.part_rotation_deg) or (0.0, 0.0, 0.0)
    return motion_entry(off, rot, design.V)


def _init_worker(design_dir: str, camera: str, shown: bool = False) -> None:
    """A spawned worker: loads the design and the camera profile itself (``shown``: progress lines on)."""
    _one_thread()
    progress.show(shown)
    _WORKER.update(design=Design(Path(design_dir)), profile=usable_profile(Path(camera)), cache={})


def _adopt(design: Design, profile, cache: dict) -> None:
    """A forked worker: keeps the parent's design, profile and print grid (shared, copy on write).

    OpenCV is on one thread already (see :func:`validate_in_pool`): reconfiguring its pool here
    would wait forever for the parent's pool threads, which a fork does not copy.
    """
    import numba

    numba.set_num_threads(1)
    _WORKER.update(design=design, profile=profile, cache=cache)


def validate_in_pool(jobs: int, work: list[tuple], design: Design, profile, profile_path: Path, cache: dict) -> list:
    """Photos scored by ``jobs`` worker processes, each on one thread; results in the photos' order.

    Processes, not threads: most of the work holds the GIL between numpy calls. The results
    come back in the order of ``work``, so the outputs do not depend on the scheduling.
    Where :func:`fork_is_safe`, the workers are forked once this process has what every photo
    needs (the print grid, which the part's summary needs here too), and ``cache`` then holds
    the grid; elsewhere they are spawned and load the design. (A photo's pictures are drawn
    with OpenCV: no worker imports matplotlib.)
    """
    if not fork_is_safe():
        context, initargs = get_context("spawn"), (str(design.dir), str(profile_path), progress.shown())
        with ProcessPoolExecutor(jobs, mp_context=context, initializer=_init_worker, initargs=initargs) as pool:
            return list(pool.map(_validate_in_worker, work))
    cache["grid"] = design_print_grid(design)
    # OpenCV's thread pool stopped before the fork (the workers inherit one thread): a forked
    # worker that reconfigured it hung, waiting on a condition variable of pool threads that
    # exist only here
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with ProcessPoolExecutor(
            jobs, mp_context=get_context("fork"), initializer=_adopt, initargs=(design, profile, cache)
        ) as pool:
            return list(pool.map(_validate_in_worker, work))
    finally:
        cv2.setNumThreads(threads)


def fork_is_safe() -> bool:
    """Whether worker processes may be forked from this one (else they are spawned).

    Forking saves each worker its start-up (Python, NumPy, OpenCV, numba, matplotlib, the
    design and the print grid: about 4 CPU s each) but needs every thread pool the parent
    has started to survive a fork. OpenCV's does once stopped (:func:`validate_in_pool`);
    numba's OpenMP layer (GNU libgomp) does not: forked workers hung in their first parallel
    loop. So fork only on Linux (macOS frameworks are not fork-safe either), and only where
    numba has not started a layer yet (it is then told to pick a fork-safe one: TBB, or its
    own work queue) or started a fork-safe one.
    """
    if not sys.platform.startswith("linux"):
        return False
    import numba

    try:
        layer = numba.threading_layer()
    except ValueError:  # no parallel loop has run in this process yet
        numba.config.THREADING_LAYER = "forksafe"
        return True
    return layer in ("tbb", "workqueue")


def read_output_profile(path: Path) -> bytes:
    """The soft proof's output ICC profile, or an error naming the file."""
    from workbench.printing.icc import profile_info

    if not path.is_file():
        raise WorkbenchError(f"{path}: --output-profile: no such file")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise WorkbenchError(f"{path}: --output-profile: {exc.strerror or exc}") from None
    space, _ = profile_info(data, f"{path}: --output-profile")
    if space not in ("CMYK", "RGB"):
        raise WorkbenchError(f"{path}: --output-profile: a {space} profile; an output (CMYK or RGB) profile is needed")
    return data


def usable_profile(path: Path):
    """The camera profile, or why no camera has it (every photo is then INVALID with that reason)."""
    try:
        return load_camera_profile(path)
    except WorkbenchError as exc:
        return str(exc)


def _validate_in_worker(job: tuple) -> tuple[dict, dict, np.ndarray | None, dict]:
    photo, stem, view, tolerance_mm, max_defect_mm2, seat, colour, finish = job
    return _timed(
        Path(photo), _WORKER["design"], _WORKER["profile"], view, tolerance_mm, _WORKER["cache"], stem, max_defect_mm2,
        seat, colour, finish,
    )  # fmt: skip


def _timed(
    path, design, profile, view, tolerance_mm, cache, stem, max_defect_mm2, seat=("on", 2.0, None), colour=None,
    finish="glossy",
):  # fmt: skip
    """:func:`validate_photo`, timed; ``colour``: (max_delta_e, the soft proof's output profile bytes or None)."""
    max_delta_e, proof = colour or (MAX_DELTA_E, None)
    t0 = time.perf_counter()
    entry, pics, state, pages = validate_photo(
        path, design, profile, view, tolerance_mm, cache, stem, max_defect_mm2, seat[0], seat[1], max_delta_e, proof,
        held=seat[2], finish=finish,
    )  # fmt: skip
    entry["seconds"] = round(time.perf_counter() - t0, 3)
    return entry, pics, state, pages


def part_seating(
    entries: list[dict], design: Design, mode: str, max_seating_mm: float, held: dict | None = None
) -> dict | None:
    """The part's seating from all its photos (each photo's own stays in its entry); drops their normal matrices.

    ``held``: where the fixture holds the part (:func:`held_pose`); the seating is the motion from there.
    """
    from workbench.validate.seating import fuse, held_vertices, seating_entry

    if mode == "off":
        return {"mode": "off"}
    V = held_vertices(design.V, held)
    seatings = [e.get("seating") for e in entries]
    fused = fuse(seatings, V)
    for s in seatings:
        if s:
            s.pop("_H", None)
            s.pop("_rho", None)
    if fused is None:
        return None
    seat, n = fused
    out = {"source": f"all photos of the part ({n})", **seating_entry(seat, V, max_seating_mm)}
    out.pop("contour_samples", None)
    out.pop("contour_rms_px", None)
    return out


def keep_freed_memory() -> None:
    """glibc's malloc: arrays of up to 32 MB from the memory the previous ones freed, not from fresh pages.

    By default glibc maps a large array anew and unmaps it when it is freed (and returns the
    heap's free top to the system): every array of a photo's analysis then costs page faults
    and the kernel's zeroing of its pages (a dense analysis of a 12 Mpx photo, called again:
    75,000 faults and 0.2 to 0.6 s of system time, measured; 400 to 16,000 faults and 0.01 to
    0.07 s with this). The thresholds at glibc's largest keep the freed memory for the next
    arrays; the peak is the same. Another C library (macOS, musl): nothing changes.
    """
    import ctypes
    import ctypes.util

    try:
        mallopt = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").mallopt
    except (OSError, AttributeError):
        return
    m_trim_threshold, m_mmap_threshold = -1, -3  # glibc's malloc.h
    mallopt(m_mmap_threshold, 32 * 1024 * 1024)  # (its largest: DEFAULT_MMAP_THRESHOLD_MAX on 64 bits)
    mallopt(m_trim_threshold, 1 << 30)


def record(recorder, report_text: str, out: Path, written: list[Path]) -> None:
    """The validation recorded in the store, in one transaction, once its outputs are written.

    ``report_text``: validation.json as written (the store keeps it as it is, and its figures as columns).
    """
    from workbench.environment import source_date_epoch
    from workbench.store.record import record_validation, recorded_at, validation_rows

    rows = validation_rows(report_text, out, written, recorder, recorded_at(source_date_epoch(os.environ)))
    try:
        record_validation(rows, recorder.url)
    except WorkbenchError as exc:
        raise WorkbenchError(f"{exc}; {out} was written but the validation is not recorded") from None


def run(args) -> int:
    keep_freed_memory()
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    # a line per photo and stage on a terminal (workers forked later keep the setting)
    progress.show(progress.wanted(args.quiet))
    if not (np.isfinite(args.tolerance_mm) and args.tolerance_mm > 0):
        raise UsageError(f"--tolerance-mm {args.tolerance_mm:g}: must be a positive number of mm")
    if not (np.isfinite(args.max_defect_mm2) and args.max_defect_mm2 > 0):
        raise UsageError(f"--max-defect-mm2 {args.max_defect_mm2:g}: must be a positive number of mm²")
    if not (np.isfinite(args.max_delta_e) and args.max_delta_e > 0):
        raise UsageError(f"--max-delta-e {args.max_delta_e:g}: must be a positive ΔE00")
    if args.jobs < 0:
        raise UsageError(f"--jobs {args.jobs}: must be 0 (every core) or more")
    recorder = store_recorder(args)
    profile_path = Path(args.camera)
    if not profile_path.is_file():
        load_camera_profile(profile_path)  # raises: missing, or a directory, in one line
    # a profile no camera has (K zero, NaN, negative fx): every photo INVALID with the reason, the report written
    profile = usable_profile(profile_path)
    design = Design(Path(args.design))
    if design.owner is None:
        raise WorkbenchError(f"{design.dir / 'owner.png'}: missing or unreadable; rerun workbench design")
    held = held_pose(args, design)
    names = [v["name"] for v in design.info["views"]]
    if args.view is not None and args.view not in names:
        raise WorkbenchError(f"no view named {args.view!r} in {design.dir / 'design.json'} (views: {', '.join(names)})")
    out = Path(args.out) if args.out else design.dir / "validation"
    jobs = args.jobs or os.cpu_count() or 1
    jobs = min(jobs, len(args.photos))
    entries, files, states = [], {}, []
    cache: dict = {}
    photos = [Path(p) for p in args.photos]
    output_profile = Path(args.output_profile) if args.output_profile else None
    inputs = [*design_files(design.dir), profile_path, *photos, *([output_profile] if output_profile else [])]
    check_output_dir(out, inputs)
    check_outputs(out / "validation.json", out / "qa_report.pdf", out / "qa_report.html", inputs=inputs)
    proof = read_output_profile(output_profile) if output_profile else None
    stems = output_stems(photos)
    seat = (args.seating, args.max_seating_mm, held)
    judge = (args.view, args.tolerance_mm, args.max_defect_mm2, seat, (args.max_delta_e, proof), args.finish)
    work = [(p, stem, *judge) for p, stem in zip(photos, stems, strict=True)]
    progress.say(f"{len(work)} photo(s) of {design.dir}, {jobs} at a time")
    if jobs > 1:
        results = validate_in_pool(jobs, work, design, profile, profile_path, cache)
    else:
        results = (
            _timed(Path(p), design, profile, v, t, cache, stem, m, st, c, f) for p, stem, v, t, m, st, c, f in work
        )
    pages: dict = {}
    for photo, (entry, pics, state, shown) in zip(photos, results, strict=True):
        entry["photo"] = recorded_path(photo, out)  # relative to the report's folder, beside its sha256
        entries.append(entry)
        states.append(state)
        files.update({out / k: v for k, v in pics.items()})
        pages.update(shown)
        mm = entry.get("misregistration_mm", {}) or {}
        log(
            f"{Path(photo).name}: {entry['verdict']}"
            + (f" ({entry.get('view')}, p95 {mm['p95']:.3f} mm)" if mm.get("p95") is not None else "")
            + f": {entry['reason']}"
        )
    scored = any(s is not None for s in states)
    grid = print_grid_of(cache) if scored else None
    if grid is None and scored:
        grid = design_print_grid(design)
    t_part = time.perf_counter()
    progress.say(f"the part: its {len(entries)} photo(s) together (defects, colour, coverage)")
    maps = detection.part_maps(entries)
    centres = [(e.get("pose") or {}).get("camera_center_mm") for e in entries]
    if maps and grid is not None:
        # one film, one slide: the photos' measures fused find what each alone may not (where two
        # of them see it from directions no one lamp serves both)
        maps["part_shift_limit_um"] = fused_part_limit(maps, grid.X, centres, args.tolerance_mm)
    slides = [e.pop("slide_measure", None) for e in entries]
    # several photos, one part: ink gone or a slide that another photo sees intact is light where it was found
    dismissed = (
        light_in_one_photo(entries, states, maps, grid.px_per_mm, args.max_defect_mm2, grid.X, slides) if grid else []
    )
    # one film, one slide: what no photo alone found significant, their measures fused can
    fusion = FusionOptions(args.tolerance_mm, args.max_defect_mm2)
    together, together_light = (
        slides_found_together(slides, entries, dismissed, grid, fusion, names) if grid else ([], [])
    )
    del slides  # (23 bytes a grid pixel a photo: not kept through the reports)
    # one print, one colour: each print pixel judged in the photo that sees it most squarely
    colour, colour_map = fused_colour(take_colour_maps(entries), photo_names(entries), args.max_delta_e)
    # an open region (a defect or a glint: the photo could not tell) that another photo from far
    # enough away found at the same print position stays on the print: a defect
    told = open_told_elsewhere(entries, states, grid.px_per_mm, args.max_defect_mm2, grid.X, dismissed) if grid else []
    in_part = {}
    for k, e in enumerate(entries):
        gone = {x["id"] for x in dismissed if x["photo_index"] == k}
        told_here = {x["id"]: x for x in told if x["photo_index"] == k}
        colour_failed = colour is not None and (e.get("colour") or {}).get("verdict") == "FAIL"
        if not gone and not colour_failed and not told_here:
            continue
        kept = {
            **e,
            "defects": [
                decided_in_part(d, told_here.get(d.get("id")), args.max_defect_mm2)
                for d in e["defects"]
                if d.get("id") not in gone
            ],
        }
        if colour_failed:
            kept.pop("colour")  # (the part's colour is judged over all its photos)
        in_part[k] = photo_verdict(kept, args.tolerance_mm, args.max_defect_mm2, args.max_delta_e)
    for x in dismissed + together_light:
        log(f"{x['photo']}: {x['kind']} of {x['area_mm2']:.1f} mm² is light: {x['decided_by']['words']}")
    for x in told:
        log(
            f"{x['photo']}: the open region of {x['area_mm2']:.1f} mm² is {x['decided_by']['hypothesis']}: "
            f"{x['decided_by']['words']}"
        )
    for d in together:
        log(
            f"the part: {d['kind']} of {d['area_mm2']:.1f} mm² found by its photos together: {d['decided_by']['words']}"
        )
    part, combined, part_defects = part_summary(states, grid, names, entries, dismissed + told, in_part, colour)
    add_found_together(part, together)
    # regions still open over the verdict's area: no photo of the part told a defect from light there
    still = [d for d in part.get("defects", []) if still_open(d, args.max_defect_mm2)]
    if part["verdict"] == "PASS" and still:
        part["verdict"] = "INCOMPLETE"  # (found by a photo that is INVALID for its texture, say)
    if part["verdict"] == "INCOMPLETE" and "reason" not in part:
        if still:
            part["reason"] = open_reason(still, args.max_defect_mm2)
        else:
            part["reason"] = next(
                in_part.get(k, (e["verdict"], e["reason"]))[1]
                for k, e in enumerate(entries)
                if in_part.get(k, (e["verdict"], None))[0] == "INCOMPLETE"
            )
    if dismissed or together_light:
        part["dismissed"] = [{k: v for k, v in x.items() if k != "photo_index"} for x in dismissed] + together_light
    if told:
        part["open_decided"] = [{k: v for k, v in x.items() if k != "photo_index"} for x in told]
    if in_part:
        part["photo_verdicts_in_part"] = {Path(entries[k]["photo"]).name: v for k, (v, _) in in_part.items()}
        part["photo_reasons_in_part"] = {Path(entries[k]["photo"]).name: r for k, (_, r) in in_part.items()}
    if colour_map is not None:
        files[out / "colour_print.png"] = png_bytes(
            pictures.colour_difference(grid.reference, colour_map, grid.px_per_mm, 2 * args.max_delta_e)
        )
    part["seating"] = part_seating(entries, design, args.seating, args.max_seating_mm, held)
    if maps and combined is not None:
        # a PASS is evidence only where the photos could have found something: with less than
        # --min-coverage of a film covered for a defect class, the part is INCOMPLETE
        opts = CoverageOptions(args.tolerance_mm, args.max_delta_e, args.min_coverage, args.max_defect_mm2)
        centres = [e["pose"]["camera_center_mm"] for e in entries if (e.get("pose") or {}).get("camera_center_mm")]
        intrinsics = profile if not isinstance(profile, str) else None
        seen_from = (
            design.V,
            design.F,
            np.asarray(centres, np.float64).reshape(-1, 3),
            intrinsics,
            design.orbit_camera,
        )
        px = [((e.get("dense") or {}).get("resolution") or {}).get("photo_px_per_mm") for e in entries]
        px = max((v for v in px if v), default=None)
        part["coverage"], uncovered = part_coverage(maps, grid, combined, seen_from, opts, px)
        if part["verdict"] == "INCOMPLETE" and still and intrinsics is not None:
            # the photo that decides the open regions: one that sees them from more than 16° away
            # from every photo that already did (where no one glint shows in both)
            nxt = open_next_photo(still, combined, grid, seen_from)
            if nxt is not None:
                part["coverage"]["next_photo"] = nxt
                part["reason"] += f"; {next_photo_line(nxt)}"
        if part["verdict"] == "PASS" and not part["coverage"]["complete"]:
            part["verdict"] = "INCOMPLETE"
            advice = next_photo_words(part["coverage"])
            part["reason"] = coverage_words(part["coverage"]["films"], opts) + (f"; {advice}" if advice else "")
        files[out / "uncovered_print.png"] = pictures.uncovered_figure(
            grid.reference,
            uncovered,
            part["coverage"]["uncovered"]["regions"],
            grid.px_per_mm,
            f"where the part's {part['photos_scored']} photo(s) cannot find a defect: {part['verdict']}",
        )
    # the part's own stage: its photos fused, its coverage and the next photo (pictures aside)
    part["seconds"] = round(time.perf_counter() - t_part, 3)
    if combined is not None:
        files[out / "coverage_print.png"] = pictures.coverage_figure(
            combined,
            grid.px_per_mm,
            f"the part's print over {part['photos_scored']} photo(s): {part['verdict']}",
            part_defects,
        )
    report = {
        "software": {"name": "workbench", "version": __version__},
        "design": {
            "dir": recorded_path(design.dir, out),
            "job": design.info.get("job"),
            "design_json_sha256": sha256(design.dir / "design.json"),
            "print_sha256": sha256(design.dir / "print.png"),
        },
        "camera_profile": {"file": recorded_path(profile_path, out), "sha256": sha256(profile_path)},
        "tolerance_mm": args.tolerance_mm,
        "max_defect_mm2": args.max_defect_mm2,
        "max_delta_e": args.max_delta_e,
        "soft_proof": (
            {"output_profile": recorded_path(output_profile, out), "sha256": sha256(output_profile)}
            if output_profile
            else {"output_profile": None, "note": "the design's sRGB as it is (no --output-profile)"}
        ),
        "verdict_rule": verdict_rule(
            args.tolerance_mm, args.max_defect_mm2, args.max_delta_e, args.min_coverage, args.finish
        ),
        "part": part,
        "photos": entries,
    }
    if held is not None:
        # (only when given: a report of a part held as designed keeps its bytes)
        report["part_held"] = held
    files.update(landing.add_to_report(report, entries, out))
    files.update(detection.add_to_report(report, maps, out))
    files[out / "validation.json"] = (json.dumps(report, indent=1) + "\n").encode()
    shown = {k.name: v for k, v in files.items() if k.suffix == ".png"}
    progress.say(f"the QA report: {out / 'qa_report.pdf'}")
    files[out / "qa_report.pdf"] = qa_report(report, shown, pages)
    files[out / "qa_report.html"] = interactive_report(report, shown, design, grid, combined, photos)
    write_folder(out, files, inputs)
    if recorder is not None:
        record(recorder, files[out / "validation.json"].decode(), out, list(files))
        log(f"recorded part {recorder.part_id}" + (f" of lot {recorder.lot}" if recorder.lot else ""))
    why = f" ({part['reason']})" if part.get("reason") else ""
    log(
        f"{len(entries)} photo(s), part: {part['verdict']}{why}; wrote {out / 'validation.json'} and "
        f"{out / 'qa_report.pdf'} (and qa_report.html)"
    )
    return 0

"""``workbench render``: synthetic photos of the decorated part on its fixture, with their truth."""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import cv2
import numpy as np

from workbench import __version__
from workbench.atomic import check_output_dir, check_outputs, safe_name, write_files, write_folder
from workbench.camera import Camera, load_camera, load_camera_profile
from workbench.design import physical_memory
from workbench.design_dir import Design, design_files
from workbench.errors import UsageError, WorkbenchError
from workbench.export import png_bytes
from workbench.jsonfile import recorded_path
from workbench.options import Number, parse_number, parse_numbers, parse_part_offset, parse_part_rotation
from workbench.render.defects import Defect
from workbench.render.imperfections import REALISTIC, Imperfections
from workbench.render.photo import render_photo
from workbench.text import ascii_text


def add_parser(sub) -> None:
    p = sub.add_parser(
        "render",
        help="synthetic photos of the decorated part (and its fixture), with controlled imperfections",
        description=(
            "Render the decorated part of a design directory, on its fixture plate, from a designed view, a "
            "camera file or an orbit position. Writes PHOTO.png (or .jpg) and PHOTO.json: the truth (K, "
            "distortion, R, t, image size, every imperfection), in the form of a camera profile. --previews "
            "writes one image per designed view, one from a generic viewpoint and a contact sheet. --renderer "
            "mitsuba renders the same scene with Mitsuba 3's path tracer (pip install mitsuba) instead of the "
            "workbench's own rasteriser: an independent image formation for the tests of validate."
        ),
    )
    p.add_argument("design", metavar="DESIGN_DIR")
    cam = p.add_mutually_exclusive_group(required=True)
    cam.add_argument("--view", metavar="NAME", help="a designed view's camera")
    cam.add_argument("--camera", metavar="CAMERA.json", help="K, dist, R, t, image_size (e.g. another PHOTO.json)")
    cam.add_argument(
        "--orbit", metavar="AZ,EL,DIST", help="look at the part from azimuth/elevation (deg) and distance (mm)"
    )
    cam.add_argument(
        "--previews", action="store_true", help="every designed view and a generic one, and a contact sheet"
    )
    p.add_argument(
        "-o", "--output", metavar="PHOTO.png", help="photo file (default photo.png; --previews: DESIGN_DIR/previews)"
    )
    p.add_argument("--size", metavar="WxH", help="image size in pixels (orbit default 1600x1200; view: the view's)")
    p.add_argument(
        "--fov-deg",
        action=Number,
        lo=0,
        hi=180,
        lo_open=True,
        hi_open=True,
        help="horizontal field of view for --orbit (default 40)",
    )
    p.add_argument("--intrinsics", metavar="PROFILE.json", help="camera profile (K, dist, image_size) for --orbit")
    p.add_argument("--no-fixture", action="store_true", help="the part alone, without its fixture plate")
    p.add_argument(
        "--supersample",
        action=Number,
        lo=1,
        hi=8,
        integer=True,
        help="samples per pixel along each axis (default 2; --renderer workbench)",
    )
    p.add_argument(
        "--renderer",
        choices=("workbench", "mitsuba"),
        default="workbench",
        help="workbench (default): the project's rasteriser; mitsuba: Mitsuba 3's path tracer (scalar_rgb, CPU), "
        "--shading, --light, --ambient, --gloss and --shininess becoming its lamp, sky and film coating",
    )
    p.add_argument(
        "--spp",
        action=Number,
        lo=1,
        # (4096 samples of a 12 Mpx photo take about nine hours here)
        hi=4096,
        integer=True,
        help="samples per pixel (default 16; --renderer mitsuba)",
    )
    g = p.add_argument_group("imperfections (all off by default)")
    g.add_argument("--realistic", action="store_true", help="blur 1 px, noise 3, JPEG 90, shading, vignetting 0.15")
    g.add_argument(
        "--film-offset-mm",
        metavar="[K:]DX,DY",
        action="append",
        help="film moved on the part, print coordinates (x right, y down); K:DX,DY moves film K (1-based) of a "
        "design with several films alone (repeatable)",
    )
    g.add_argument(
        "--film-rotation-deg",
        action=Number,
        lo=-360,
        hi=360,
        help="film rotated about the print's centre, counter-clockwise",
    )
    g.add_argument(
        "--film-scale-pct", action=Number, lo=-50, hi=100, help="film uniformly larger by this percentage (-50 to 100)"
    )
    g.add_argument("--print-scale-pct", metavar="SX,SY", help="printer scale error in x and y, percent")
    g.add_argument("--distortion", metavar="K1,K2,P1,P2,K3", help="lens distortion (OpenCV order)")
    g.add_argument("--blur-px", action=Number, lo=0, hi=50, help="Gaussian blur sigma, pixels")
    g.add_argument("--noise", action=Number, lo=0, hi=100, help="Gaussian noise sigma, grey levels")
    g.add_argument("--exposure", action=Number, lo=0, hi=100, help="multiplies intensity")
    g.add_argument("--gamma", action=Number, lo=0.05, hi=20, help="output = input ^ (1 / gamma)")
    g.add_argument("--shading", action="store_true", default=None, help="Lambertian shading")
    g.add_argument("--light", metavar="X,Y,Z", help="direction towards the light (world)")
    g.add_argument("--ambient", action=Number, lo=0, hi=1, help="ambient share of the light (default 0.35)")
    g.add_argument(
        "--gloss",
        action=Number,
        lo=0,
        hi=1,
        help="glossy film: strength of the light's specular highlight (0 to 1; 0: matte)",
    )
    g.add_argument(
        "--shininess",
        action=Number,
        lo=1,
        hi=10000,
        help="Blinn-Phong exponent of the highlight (default 80: small, sharp)",
    )
    g.add_argument(
        "--defect",
        metavar="KIND:...",
        action="append",
        help=(
            "a local film defect, print mm (x right, y down), repeatable: bubble:X,Y,R,SHIFT (a disc of radius R "
            "where the print slid SHIFT mm along +x; or bubble:X,Y,R,DX,DY), scratch:X0,Y0,X1,Y1,W (ink gone along "
            "a line W mm wide), dropout:X,Y,R (ink missing in a disc)"
        ),
    )
    g.add_argument(
        "--forming",
        metavar="FIELD",
        help="the film lands by a known law: print point p lands where the design puts p + d(p); FIELD is "
        "KIND:A,B[,...] terms joined by '+' (stretch:SX,SY, creep:AX,AY, draw:A, wave:AX,AY,L, shift:DX,DY; "
        "amplitudes mm at the print's edge) or a forming profile (.json, workbench calibrate forming)",
    )
    g.add_argument(
        "--forming-random-mm",
        action=Number,
        lo=0,
        hi=100,
        help="a per-sheet random film placement added to the landing: a shift of this standard deviation (mm) "
        "along each axis, drawn from --seed",
    )
    g.add_argument("--vignetting", action=Number, lo=0, hi=1, help="brightness loss at the corners (0 to 1)")
    g.add_argument("--jpeg-quality", action=Number, lo=1, hi=100, integer=True, help="JPEG round trip at this quality")
    g.add_argument(
        "--colour-shift-lab",
        metavar="DL,DA,DB",
        help="every colour of the print shifted in CIELAB (D50), e.g. -6,6,8: a wrong ink or profile",
    )
    g.add_argument(
        "--white-balance",
        metavar="R,G,B",
        help="a coloured light: linear gains per channel on the whole scene, e.g. 1.1,1,0.85 (warm)",
    )
    g.add_argument(
        "--part-offset-mm",
        metavar="X,Y[,Z]",
        help="the part set down off its outline: its centre (the bounding box's) moved by this on the plate, mesh "
        "frame, mm (the truth is in PHOTO.json's part_pose: X_photo = R X_design + t)",
    )
    g.add_argument(
        "--part-rotation-deg",
        metavar="RX,RY,RZ",
        help="the part turned about its centre by RX, RY, RZ degrees about the mesh frame's axes (R = Rz Ry Rx)",
    )
    g.add_argument(
        "--seed",
        action=Number,
        lo=0,
        hi=2**32 - 1,
        integer=True,
        default=0,
        help="noise seed (and the path tracer's sampler seed)",
    )
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(run=run)


# what each list option's numbers may be: beyond, a photo is nothing but overflow
LIMITS = {
    "--film-offset-mm": {"lo": -1000, "hi": 1000, "unit": "mm"},
    "--print-scale-pct": {"lo": -50, "hi": 100},
    "--distortion": {"lo": -100, "hi": 100},
    "--light": {"lo": -1e6, "hi": 1e6},
    "--colour-shift-lab": {"lo": -50, "hi": 50},
    "--white-balance": {"lo": 0.1, "hi": 10},
}


def _floats(text: str | None, n: int, flag: str) -> tuple | None:
    if text is None:
        return None
    return parse_numbers(text, n, flag, **LIMITS.get(flag, {}))


def _orbit(text: str) -> tuple[float, float, float]:
    """``AZ,EL,DIST``: azimuth and elevation in degrees, distance in mm."""
    az, el, dist = parse_numbers(text, 3, "--orbit")
    for value, name, lo, hi in ((az, "azimuth", -3600, 3600), (el, "elevation", -90, 90)):
        parse_number(str(value), f"--orbit {text}: {name}", lo, hi, unit="degrees")
    parse_number(str(dist), f"--orbit {text}: distance", 0, 1e6, lo_open=True, unit="mm")
    return az, el, dist


def _direction(text: str | None, flag: str) -> tuple | None:
    vals = _floats(text, 3, flag)
    if vals is not None and not np.linalg.norm(vals) > 0:
        raise UsageError(f"{flag} {text!r}: a direction cannot be zero")
    return vals


def _whole_film_offset(values: list[str] | None) -> str | None:
    """The one --film-offset-mm without a film number, if any."""
    whole = [v for v in values or [] if ":" not in v]
    if len(whole) > 1:
        raise UsageError("--film-offset-mm DX,DY: give it once (K:DX,DY moves film K alone)")
    return whole[0] if whole else None


def _per_film_offsets(values: list[str] | None) -> tuple | None:
    """``K:DX,DY`` values as ((K, DX, DY), ...); None without any."""
    out = []
    for v in values or []:
        if ":" not in v:
            continue
        k, _, rest = v.partition(":")
        if not k.strip().isdigit() or int(k) < 1:
            raise UsageError(f"--film-offset-mm {v!r}: K:DX,DY with K a film number from 1")
        dx, dy = _floats(rest, 2, "--film-offset-mm")
        if any(f == int(k) for f, _, _ in out):
            raise UsageError(f"--film-offset-mm {v!r}: film {k} is moved twice")
        out.append((int(k), dx, dy))
    return tuple(out) or None


def imperfections_from(args) -> Imperfections:
    """The imperfections the command line asks for (preset first, then explicit flags)."""
    kw: dict = dict(REALISTIC) if args.realistic else {}
    pairs = {
        "film_offset_mm": _floats(_whole_film_offset(args.film_offset_mm), 2, "--film-offset-mm"),
        "film_offsets_mm": _per_film_offsets(args.film_offset_mm),
        "film_rotation_deg": args.film_rotation_deg,
        "film_scale_pct": args.film_scale_pct,
        "print_scale_pct": _floats(args.print_scale_pct, 2, "--print-scale-pct"),
        "distortion": _floats(args.distortion, 5, "--distortion"),
        "blur_px": args.blur_px,
        "noise": args.noise,
        "exposure": args.exposure,
        "gamma": args.gamma,
        "shading": args.shading,
        "light": _direction(args.light, "--light"),
        "ambient": args.ambient,
        "vignetting": args.vignetting,
        "gloss": args.gloss,
        "shininess": args.shininess,
        "jpeg_quality": args.jpeg_quality,
        "colour_shift_lab": _floats(args.colour_shift_lab, 3, "--colour-shift-lab"),
        "white_balance": _floats(args.white_balance, 3, "--white-balance"),
        "part_offset_mm": parse_part_offset(args.part_offset_mm),
        "part_rotation_deg": parse_part_rotation(args.part_rotation_deg),
    }
    kw.update({k: v for k, v in pairs.items() if v is not None})
    kw["seed"] = args.seed
    defects = []
    for spec in args.defect or []:
        try:
            defects.append(Defect.parse(spec).spec())
        except ValueError as exc:
            raise UsageError(f"--defect {spec!r}: {exc}") from None
    kw["defects"] = tuple(defects)
    for key, lo, hi in (
        ("blur_px", 0, 50),
        ("noise", 0, 100),
        ("exposure", 0, 100),
        ("gamma", 0.05, 20),
        ("ambient", 0, 1),
        ("vignetting", 0, 1),
        ("gloss", 0, 1),
        ("shininess", 1, 10000),
        ("jpeg_quality", 1, 100),
    ):
        if key in kw and not lo <= kw[key] <= hi:
            raise UsageError(f"--{key.replace('_', '-')} {kw[key]}: must be between {lo} and {hi}")
    if "colour_shift_lab" in kw and not all(abs(v) <= 50 for v in kw["colour_shift_lab"]):
        raise UsageError(f"--colour-shift-lab {args.colour_shift_lab}: each of DL, DA, DB between -50 and 50")
    if "white_balance" in kw and not all(0.1 <= v <= 10 for v in kw["white_balance"]):
        raise UsageError(f"--white-balance {args.white_balance}: each gain between 0.1 and 10")
    return Imperfections(**kw)


def _size(text: str | None, default: tuple[int, int]) -> tuple[int, int]:
    if text is None:
        return default
    if len(text.lower().split("x")) != 2:
        raise UsageError(f"--size {text!r}: give WxH in pixels, e.g. 4000x3000")
    return parse_numbers(text.lower(), 2, f"--size {text}: a side", sep="x", lo=8, hi=20000, integer=True)


# peak bytes per supersample of a render (z-buffer, face ids, barycentrics, colour, lens maps):
# 3.1 GB measured for 4000 x 3000 px at 2 x 2 samples, with a margin
BYTES_PER_SAMPLE = 80


# peak bytes per photo pixel of a Mitsuba render with a lens (a 2 x 2 times larger ideal RGBA film,
# its copies, the resampling maps and samples): 4.2 GB peak RSS measured for 4000 x 3000 px
# (benchmarks/bench_render_mitsuba.py), with a margin
BYTES_PER_PIXEL_MITSUBA = 400


def forming_from(args, design: Design):
    """The forming fields ``--forming`` and ``--forming-random-mm`` ask for (one per film), and their truth
    for PHOTO.json.

    Each film's field is defined on its uncompensated print (``Design.film_frames``): a law's u, v
    run across each film's own print; a profile gives one field per film. The random placement is
    drawn per film (films are formed one by one), the first film's as a design of one film's.
    Returns (None, None) without either option.
    """
    from workbench import forming as fm

    if args.forming is None and not args.forming_random_mm:
        return None, None
    frames = design.film_frames()
    record: dict = {"law": args.forming, "defined_on": "each film's uncompensated print, mm (x right, y down)"}
    fields = [[] for _ in frames]
    if args.forming is not None:
        if args.forming.lower().endswith(".json"):
            prof = fm.read_profile(Path(args.forming), f"--forming {args.forming}")
            got = fm.profile_fields(prof)
            if len(got) != len(frames):
                raise WorkbenchError(
                    f"--forming {args.forming}: a profile of {len(got)} film(s), the design has {len(frames)}"
                )
            for k, f in enumerate(got):
                fields[k].append(f)
            record["profile_sha256"] = fm.file_sha256(args.forming)
        else:
            try:
                for k, fr in enumerate(frames):
                    fields[k].append(fm.parse_law(args.forming, fr.size_mm))
            except WorkbenchError as exc:
                raise UsageError(str(exc)) from None
    if args.forming_random_mm:
        rng = np.random.default_rng([int(args.seed), 20])
        shifts = rng.normal(0.0, args.forming_random_mm, (len(frames), 2))
        for k, fr in enumerate(frames):
            fields[k].append(fm.Placement(tuple(shifts[k]), 0.0, (0.5 * fr.size_mm[0], 0.5 * fr.size_mm[1])))
        record["random_mm"] = args.forming_random_mm
        record["random_shift_mm"] = shifts[0].tolist() if len(frames) == 1 else shifts.tolist()
    out = [f[0] if len(f) == 1 else fm.Sum(f[0], f[1]) for f in fields]
    return out, record


def check_render_fits(width: int, height: int, supersample: int | None, renderer: str = "workbench") -> None:
    """Refuse, before any work, a photo whose buffers would not fit in this machine's memory."""
    if renderer == "mitsuba":
        need, knob = width * height * BYTES_PER_PIXEL_MITSUBA, ""
    else:
        need, knob = width * height * supersample**2 * BYTES_PER_SAMPLE, f" with --supersample {supersample}"
    have = physical_memory()
    if need > 0.7 * have:
        raise WorkbenchError(
            f"--size {width}x{height}{knob} needs about {need / 2**30:,.1f} GiB; "
            f"this machine has {have / 2**30:.1f} GiB available: lower --size" + (" or --supersample" if knob else "")
        )


def check_camera_options(args) -> None:
    """Options that only one way of giving the camera reads are refused with the others, not ignored."""
    given = "--view" if args.view else "--camera" if args.camera else "--previews" if args.previews else "--orbit"
    own = {"--view": ("size",), "--orbit": ("size", "fov_deg", "intrinsics")}.get(given, ())
    for key in ("size", "fov_deg", "intrinsics"):
        if getattr(args, key) is not None and key not in own:
            flag = "--" + key.replace("_", "-")
            source = {"--camera": "the camera file", "--view": "the view", "--previews": "the previews"}[given]
            raise UsageError(f"{flag} does not apply to {given}: {source} fixes the image")
    if args.fov_deg is not None and not 0 < args.fov_deg < 180:
        raise UsageError(f"--fov-deg {args.fov_deg:g}: must be between 0 and 180")
    for key in ("fov_deg", "size"):
        if getattr(args, key) is not None and args.intrinsics is not None:
            raise UsageError(
                f"--{key.replace('_', '-')} does not apply with --intrinsics: the profile's K and image_size fix it"
            )


def check_renderer_options(args) -> None:
    """Each renderer's own sampling option is refused with the other, not ignored; fills in the defaults."""
    if args.renderer == "mitsuba":
        if args.supersample is not None:
            raise UsageError("--supersample does not apply to --renderer mitsuba: give --spp (samples per pixel)")
        if args.spp is None:
            args.spp = 16
        if not 1 <= args.spp <= 4096:
            raise UsageError(f"--spp {args.spp}: between 1 and 4096 samples per pixel")
    else:
        if args.spp is not None:
            raise UsageError("--spp applies to --renderer mitsuba; the workbench renderer takes --supersample")
        if args.supersample is None:
            args.supersample = 2
        if not 1 <= args.supersample <= 8:
            raise UsageError("--supersample: between 1 and 8")


def renderer_info(args) -> dict:
    """PHOTO.json's record of what made the photo (the truth itself does not depend on it)."""
    if args.renderer == "mitsuba":
        from workbench.render.mitsuba import VARIANT, load_mitsuba

        mi = load_mitsuba()
        return {"name": "mitsuba", "version": mi.__version__, "variant": VARIANT, "spp": args.spp, "seed": args.seed}
    return {"name": "workbench", "supersample": args.supersample}


def make_photo(args, scene, cam: Camera, imp: Imperfections) -> np.ndarray:
    """The photo by the renderer ``args.renderer`` asks for; (H, W, 3) uint8 RGB."""
    if args.renderer == "mitsuba":
        from workbench.render.mitsuba import render_photo_mitsuba  # Mitsuba is optional: imported when asked for

        return render_photo_mitsuba(scene, cam, imp, spp=args.spp, seed=args.seed)
    return render_photo(scene, cam, imp, args.supersample)


def truth(
    camera: Camera, imp: Imperfections, design: Design, source: str, out: Path, renderer: dict | None = None
) -> dict:
    """PHOTO.json: a camera profile (K, dist, image_size) with the pose and every imperfection."""
    return {
        "K": camera.K.tolist(),
        "dist": list(imp.distortion),
        "image_size": [camera.width, camera.height],
        "R": camera.R.tolist(),
        "t": camera.t.tolist(),
        "camera_center_mm": camera.center.tolist(),
        "imperfections": imp.to_dict(),
        # each defect's centre and area in print mm: what validate must find
        "defects": [Defect.parse(d).truth() for d in imp.defects],
        "part_pose": part_pose(imp, design),
        "source": source,
        # relative to the folder of PHOTO.json, as every recorded path
        "design": {
            "dir": recorded_path(design.dir, out.parent),
            "job_sha256": design.info["job"].get("sha256"),
            "design_json_sha256": hashlib.sha256((design.dir / "design.json").read_bytes()).hexdigest(),
        },
        "software": {"name": "workbench", "version": __version__},
        **({"renderer": renderer} if renderer else {}),
    }


def part_pose(imp: Imperfections, design: Design) -> dict:
    """Where the part sits on its plate: ``X_photo = R X_design + t`` (mesh frame, mm), and the motion's terms."""
    from workbench.part_motion import motion_entry

    return motion_entry(imp.part_offset_mm, imp.part_rotation_deg, design.V)


def encode(rgb: np.ndarray, path: Path, imp: Imperfections) -> bytes:
    if path.suffix.lower() not in (".jpg", ".jpeg", ".png"):
        raise UsageError(f"{path}: photos are written as .png or .jpg")
    if path.suffix.lower() in (".jpg", ".jpeg"):
        q = imp.jpeg_quality or 95
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, int(q)])
        return buf.tobytes()
    return png_bytes(rgb)


def run(args) -> int:
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    check_renderer_options(args)
    imp = imperfections_from(args)
    check_camera_options(args)
    design = Design(Path(args.design))
    renderer = renderer_info(args)  # Mitsuba missing: said before any work
    fixture = not args.no_fixture
    if args.previews:
        return previews(args, design, imp, fixture, log, renderer)
    if args.view:
        cam = design.view_camera(args.view)
        if args.size:
            w, h = _size(args.size, (cam.width, cam.height))
            if abs(h - cam.height * w / cam.width) > 1:
                raise UsageError(
                    f"--size {args.size}: the view {args.view!r} is {cam.width} x {cam.height}; "
                    "keep its aspect ratio (the view's camera is scaled, not cropped)"
                )
            cam = cam.scaled(w / cam.width)
        source = f"view {args.view}"
    elif args.camera:
        cam = load_camera(Path(args.camera))
        if np.any(cam.dist) and not np.any(imp.distortion):
            imp = Imperfections(**{**imp.to_dict(), "distortion": tuple(cam.dist)})
        source = f"camera {args.camera}"
    else:
        az, el, dist = _orbit(args.orbit)
        intr = load_camera_profile(Path(args.intrinsics)) if args.intrinsics else None
        w, h = _size(args.size, (1600, 1200))
        cam = design.orbit_camera(az, el, dist, w, h, args.fov_deg or 40.0, intr)
        if intr is not None and np.any(intr.dist) and not np.any(imp.distortion):
            imp = Imperfections(**{**imp.to_dict(), "distortion": tuple(intr.dist)})
        source = f"orbit {args.orbit}"
    out = Path(args.output or "photo.png")
    inputs = [*design_files(design.dir), *(Path(p) for p in (args.camera, args.intrinsics) if p)]
    # before the rendering, not after it; `-o DESIGN/print.png` would destroy the design
    check_outputs(out, out.with_suffix(".json"), inputs=inputs)
    if out.suffix.lower() not in (".jpg", ".jpeg", ".png"):
        raise UsageError(f"-o {out}: photos are written as .png or .jpg")
    check_render_fits(cam.width, cam.height, args.supersample, args.renderer)
    forming, forming_truth = forming_from(args, design)
    if args.forming and args.forming.lower().endswith(".json"):
        inputs.append(Path(args.forming))
    try:
        rgb = make_photo(args, design.scene(imp, fixture, forming), cam, imp)
    except WorkbenchError as exc:  # "the camera sees nothing": say which camera
        raise WorkbenchError(f"--{source}: {exc}") from None
    record = truth(cam, imp, design, source, out, renderer)
    if forming_truth:
        record["forming"] = forming_truth
    photo = {out: encode(rgb, out, imp), out.with_suffix(".json"): (json.dumps(record, indent=1) + "\n").encode()}
    write_files(photo, inputs=inputs)
    log(f"wrote {out} ({cam.width} x {cam.height}) and {out.with_suffix('.json')}")
    return 0


def previews(args, design: Design, imp: Imperfections, fixture: bool, log, renderer: dict | None = None) -> int:
    out = Path(args.output) if args.output else design.dir / "previews"
    check_output_dir(out, design_files(design.dir))
    files, tiles = {}, []
    forming, forming_truth = forming_from(args, design)
    scene = design.scene(imp, fixture, forming)
    cams = [(v["name"], design.view_camera(v["name"])) for v in design.info["views"]]
    cams.append(
        (
            "generic",
            design.orbit_camera(
                35.0, 35.0, 2.2 * float(np.linalg.norm(np.ptp(design.V, axis=0))), 1200, 900, 40.0, None
            ),
        )
    )
    for name, cam in cams:
        rgb = make_photo(args, scene, cam, imp)
        files[out / f"{safe_name(name)}.png"] = png_bytes(rgb)
        files[out / f"{safe_name(name)}.json"] = (
            json.dumps(truth(cam, imp, design, f"preview {name}", out / name, renderer), indent=1) + "\n"
        ).encode()
        h = 300
        tile = cv2.resize(rgb, (int(round(rgb.shape[1] * h / rgb.shape[0])), h), interpolation=cv2.INTER_AREA)
        tile = cv2.copyMakeBorder(tile, 30, 6, 6, 6, cv2.BORDER_CONSTANT, value=(255, 255, 255))
        cv2.putText(tile, ascii_text(name), (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (20, 20, 20), 1, cv2.LINE_AA)
        tiles.append(tile)
    sheet = np.hstack(tiles)
    files[out / "contact_sheet.png"] = png_bytes(sheet)
    write_folder(out, files, design_files(design.dir))
    log(f"wrote {len(cams)} previews and {out / 'contact_sheet.png'}")
    return 0

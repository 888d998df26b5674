"""Fuzz: every command on deterministically mutated inputs (seeded numpy RNG).

Broken meshes (truncated, NaN, out-of-range indices, non-manifold, empty), broken job
files (wrong types, missing and unknown keys, broken TOML), broken images, broken JSON
(profiles, board definitions, design.json, fixture.json) and absurd options. Each case
runs the command in-process through ``workbench.cli.main`` and asserts the convention of
the README: no exception escapes, exit status 0, 1 or 2, a failure is one line
``workbench COMMAND: error: ...`` and leaves every file as it was (earlier output intact,
nothing new). A fast subset runs by default; ``-m slow`` (``make bench``) runs 500 more
cases per command (``suggest-views`` among them).
"""

from __future__ import annotations

import copy
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT

from fixtures.make_fixtures import checker_image, domed_part, write_png
from workbench.cli import main

FAST, SLOW = 20, 500
COMMANDS = ("flatten", "design", "pdf", "board", "render", "validate", "calibrate", "suggest-views")
CALIB = ROOT / "calib"


def cases(command: str) -> list:
    """Case numbers: FAST in the default run, SLOW more marked slow."""
    fast = [pytest.param(i, id=f"{command}-{i}") for i in range(FAST)]
    slow = [pytest.param(i, id=f"{command}-{i}", marks=pytest.mark.slow) for i in range(FAST, FAST + SLOW)]
    return fast + slow


def rng_for(command: str, case: int) -> np.random.Generator:
    return np.random.default_rng([COMMANDS.index(command), case])


# --- mutations --------------------------------------------------------------------------------

ODD_VALUES = (
    None,
    "",
    "x",
    "../../escaped",
    -1,
    0,
    1,
    0.5,
    -1e308,
    1e308,
    float("nan"),
    float("inf"),
    10**30,
    True,
    [],
    {},
    [1, 2],
    [[1, 2], [3]],
    [0.0] * 9,
    "NaN",
)


def odd_value(rng):
    return copy.deepcopy(ODD_VALUES[rng.integers(len(ODD_VALUES))])


def mutate_bytes(rng, data: bytes) -> bytes:
    """Truncated, emptied, bytes flipped, garbage inserted or a slice repeated."""
    op = rng.integers(5)
    n = len(data)
    if op == 0 or n == 0:
        return data[: rng.integers(n + 1)] if n else b""
    if op == 1:
        return b""
    if op == 2:
        buf = bytearray(data)
        for i in rng.integers(0, n, size=rng.integers(1, 9)):
            buf[i] = int(rng.integers(256))
        return bytes(buf)
    if op == 3:
        at = rng.integers(n + 1)
        return data[:at] + rng.integers(0, 256, rng.integers(1, 64)).astype(np.uint8).tobytes() + data[at:]
    a = rng.integers(n)
    b = min(n, a + rng.integers(1, 200))
    return data[:b] + data[a:b] * int(rng.integers(1, 4)) + data[b:]


def _nodes(obj, path=()):
    """Every (container, key) pair of a nested JSON value."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield obj, k
            yield from _nodes(v, (*path, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield obj, i
            yield from _nodes(v, (*path, i))


def mutate_json(rng, data):
    """One to three edits anywhere in a JSON value: a key deleted, an odd value, a number changed, a key added."""
    data = copy.deepcopy(data)
    for _ in range(rng.integers(1, 4)):
        nodes = list(_nodes(data))
        if not nodes:
            return odd_value(rng)
        parent, key = nodes[rng.integers(len(nodes))]
        op = rng.integers(4)
        if op == 0:
            del parent[key]
        elif op == 1:
            parent[key] = odd_value(rng)
        elif op == 2 and isinstance(parent[key], int | float) and not isinstance(parent[key], bool):
            parent[key] = parent[key] * float(rng.choice([-1.0, 0.0, 1e-9, 1.5, 1e9]))
        elif isinstance(parent, dict):
            parent["unknown_" + str(rng.integers(100))] = odd_value(rng)
        else:
            parent.append(odd_value(rng))
    return data


def write_json(path: Path, data) -> None:
    path.write_text(json.dumps(data))  # NaN and Infinity as Python writes them: readers must refuse them


def obj_text(V, F) -> bytes:
    vl = "\n".join(f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(V, float).tolist())
    fl = "\n".join(f"f {a} {b} {c}" for a, b, c in (np.asarray(F) + 1).tolist())
    return (vl + "\n" + fl + "\n").encode()


def mutate_mesh(rng, V, F) -> tuple[bytes, str]:
    """A broken variant of a mesh: (file content, suffix)."""
    V, F = np.array(V, float), np.array(F)
    op = rng.integers(12)
    if op == 0:
        V[rng.integers(len(V)), rng.integers(3)] = rng.choice([np.nan, np.inf, -np.inf])
    elif op == 1:
        F[rng.integers(len(F)), rng.integers(3)] = len(V) + rng.integers(0, 5)
    elif op == 2:
        F[rng.integers(len(F)), rng.integers(3)] = -int(rng.integers(len(V) + 1, len(V) + 9))
    elif op == 3:  # a third face on an interior edge: non-manifold
        a, b = F[rng.integers(len(F))][:2]
        V = np.vstack([V, V[a] + [0, 0, 5]])
        F = np.vstack([F, [a, b, len(V) - 1]])
    elif op == 4:
        F = F[rng.random(len(F)) > rng.uniform(0.05, 0.9)]
    elif op == 5:
        F = F[:0]
    elif op == 6:
        F[rng.integers(len(F))] = F[rng.integers(len(F))][::-1]
    elif op == 7:  # two vertices welded: degenerate faces
        a, b = rng.integers(len(V), size=2)
        F[F == a] = b
    elif op == 8:
        V = V * float(rng.choice([1e-300, 1e300, 0.0, -1.0]))
    elif op == 9:
        V = np.vstack([V, rng.normal(size=(3, 3))])
    elif op == 10:
        F = np.vstack([F, F[: rng.integers(1, 5)]])
    data = obj_text(V, F)
    if op == 11 or rng.random() < 0.25:
        data = mutate_bytes(rng, data)
    suffix = ".obj"
    if rng.random() < 0.1:
        suffix = str(rng.choice([".stl", ".ply", ".off", ".glb"]))
    return data, suffix


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if np.isnan(v) else ("inf" if v > 0 else "-inf") if np.isinf(v) else repr(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v if x is not None) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items() if x is not None) + "}"
    return json.dumps(str(v))


def toml_text(job) -> bytes:
    """A job as TOML: top-level scalars first, tables, then arrays of tables (None values left out)."""
    if not isinstance(job, dict):
        return f"job = {toml_value(job)}\n".encode()
    lines = [f"{k} = {toml_value(v)}" for k, v in job.items() if v is not None and not isinstance(v, dict | list)]
    lines += [f"{k} = {toml_value(v)}" for k, v in job.items() if isinstance(v, list) and not _tables(v)]
    for k, v in job.items():
        if isinstance(v, dict):
            lines.append(f"[{k}]")
            lines += [f"{kk} = {toml_value(vv)}" for kk, vv in v.items() if vv is not None]
    for k, v in job.items():
        if isinstance(v, list) and _tables(v):
            for item in v:
                lines.append(f"[[{k}]]")
                lines += [f"{kk} = {toml_value(vv)}" for kk, vv in item.items() if vv is not None]
    return ("\n".join(lines) + "\n").encode()


def _tables(v: list) -> bool:
    return bool(v) and all(isinstance(x, dict) for x in v)


# --- running a command ------------------------------------------------------------------------


def tree(path: Path) -> dict:
    return {p.relative_to(path): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


def run(capsys, root: Path, argv: list[str]) -> int:
    """Run one command; check the convention; return its exit status.

    Any exception but SystemExit propagates and fails the test (a traceback for the user).
    """
    capsys.readouterr()
    before = tree(root)
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse's own exits (only --help and --version would)
        status = exc.code
    err = capsys.readouterr().err
    assert "Traceback" not in err and "Warning:" not in err, err
    assert status in (0, 1, 2), (status, err)
    if status != 0:
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith((f"workbench {argv[0]}: error: ", "workbench: error: ")), lines[0]
        assert tree(root) == before, "a failed run changed files"
    return status


# --- shared inputs ----------------------------------------------------------------------------

BASE_JOB = {
    "object": {"mesh": "part.obj", "units": "mm", "material": {"name": "film", "max_stretch": 1.1}},
    "print": {"dpi": 30, "scale": "isometric", "outline": "rectangle", "background": "#ffffff", "bleed_mm": 3},
    "views": [
        {
            "name": "top",
            "image": "top.png",
            "position": [0, 0, 200],
            "look_at": [0, 0, 0],
            "up": [0, 1, 0],
            "fov_deg": 25,
        }
    ],
}


def job_inputs(folder: Path) -> None:
    """A small part (60 x 40 mm, domed 6 mm, 10 x 8 vertices) and one 320 x 240 view image."""
    from workbench.mesh.io import format_obj

    folder.mkdir(parents=True, exist_ok=True)
    V, F = domed_part(10, 8, 60.0, 40.0, 6.0)
    (folder / "part.obj").write_bytes(format_obj(V, F))
    write_png(folder / "top.png", checker_image(320, 240, 20, ((240, 240, 240), (40, 90, 200)), "top"))
    (folder / "job.toml").write_bytes(toml_text(BASE_JOB))


def make_base(root):
    """In ``root``: the small job, its design folder and a photo of it with its truth (a camera profile)."""
    job_inputs(root)
    assert main(["design", str(root / "job.toml"), "--out", str(root / "design"), "-q"]) == 0
    photo = root / "photo.png"
    argv = ["render", root / "design", "--orbit", "0,60,250", "--size", "640x480", "--supersample", "1", "-o", photo]
    assert main([str(a) for a in argv + ["-q"]]) == 0
    return root


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """The small job, its design folder and a photo of it with its truth (a camera profile)."""
    return make_base(tmp_path_factory.mktemp("fuzz-base"))


def earlier_output(folder: Path) -> None:
    """An earlier run's output that a failed run must leave as it was."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "earlier.txt").write_text("an earlier run's output")


# --- the commands -----------------------------------------------------------------------------


@pytest.mark.parametrize("case", cases("flatten"))
def test_flatten(case, tmp_path, capsys):
    rng = rng_for("flatten", case)
    from conftest import grid_corners

    from fixtures.make_fixtures import grid_mesh

    nx, ny = int(rng.integers(3, 8)), int(rng.integers(3, 7))
    P, F = grid_mesh(nx, ny, rng)
    V = np.column_stack([P * [40, 30], 3 * np.sin(3 * P[:, 0])])
    data, suffix = mutate_mesh(rng, V, F) if rng.random() < 0.85 else (obj_text(V, F), ".obj")
    mesh = tmp_path / f"m{suffix}"
    mesh.write_bytes(data)
    out = tmp_path / "out"
    earlier_output(out)
    argv = ["flatten", mesh, "--out", out, "-q"]
    if rng.random() < 0.3:
        argv += ["--corners", str(rng.choice(["auto", ",".join(map(str, grid_corners(nx, ny))), "0,1,2", "a,b,c,d"]))]
    if rng.random() < 0.3:
        argv += ["--scale", str(rng.choice(["isometric", "no-shrink", "rim", "width=50", "width=1e-300", "height=-2"]))]
    if rng.random() < 0.2:
        argv += ["--outline", "free"]
    if rng.random() < 0.2:
        argv += ["--dpi", str(rng.choice(["0", "nan", "300", "1e9"]))]
    if run(capsys, tmp_path, argv) == 0:
        assert (out / "flat.obj").is_file() and (out / "earlier.txt").is_file()


@pytest.mark.parametrize("case", cases("design"))
def test_design(case, tmp_path, capsys, base):
    rng = rng_for("design", case)
    job_dir = tmp_path / "job"

    def varied(rng):  # a job that is fine: the command must succeed on its variations too
        job = copy.deepcopy(BASE_JOB)
        job["print"]["dpi"] = int(rng.integers(10, 60))
        job["print"]["scale"] = str(rng.choice(["isometric", "no-shrink", "width=70", "rim"]))
        job["views"][0]["fov_deg"] = float(rng.uniform(15, 40))
        job["views"][0]["position"] = [float(rng.uniform(-30, 30)), float(rng.uniform(-30, 30)), 200.0]
        return job

    broken_job(rng, base, job_dir, 0.2, varied)
    out = tmp_path / "out"
    earlier_output(out)
    if run(capsys, tmp_path, ["design", job_dir / "job.toml", "--out", out, "-q"]) == 0:
        assert (out / "design.json").is_file() and (out / "earlier.txt").is_file()


@pytest.mark.parametrize("case", cases("suggest-views"))
def test_suggest_views(case, tmp_path, capsys, base):
    # the job broken as design's is (its values, its bytes, its mesh, its view image), or fine, with
    # the options drawn from the absurd to the usual; a template the user drew on is never replaced
    rng = rng_for("suggest-views", case)
    job_dir = tmp_path / "job"
    broken_job(rng, base, job_dir, 0.3, lambda _rng: BASE_JOB)
    out = tmp_path / "out"
    earlier_output(out)
    drawn = out / "suggest-1.png"
    if rng.random() < 0.3:
        drawn.parent.mkdir(parents=True, exist_ok=True)
        write_png(drawn, np.tile(np.uint8([[30], [220]]), (24, 64))[..., None].repeat(3, axis=2))  # drawn on
    argv = ["suggest-views", job_dir / "job.toml", "-o", out / "suggest.toml", "-q"]
    options = {
        "-n": ["0", "1", "2", "-1", "x", "1e9", "3"],
        "--distance-mm": ["200", "0", "-5", "nan", "100,400", "400,100", "1e300", "a,b"],
        "--min-elevation-deg": ["10", "-90", "90", "91", "nan"],
        "--up": ["0,0,1", "0,0,0", "1,nan,0", "x"],
        "--fov-deg": ["30", "0", "179", "180", "-1"],
        "--size": ["320x240", "0x0", "1x1", "100000x100000", "axb"],
        "--max-obliquity-deg": ["60", "0", "90", "-1"],
        "--min-separation-deg": ["20", "0", "180", "-5"],
    }
    for flag, values in options.items():
        if rng.random() < 0.25:
            argv += [flag, str(rng.choice(values))]
    before = drawn.read_bytes() if drawn.exists() else None
    if run(capsys, tmp_path, argv) == 0:
        assert (out / "suggest.toml").is_file() and (out / "earlier.txt").is_file()
    if before is not None:
        assert drawn.read_bytes() == before, "a template drawn on was replaced"


def broken_job(rng, base: Path, job_dir: Path, fine_share: float, fine) -> None:
    """A job folder from the base's files, broken one way or fine: ``fine(rng)``'s job with ``fine_share``,
    else its values, its bytes, its mesh or its view image broken."""
    job_dir.mkdir()
    for name in ("part.obj", "top.png"):
        shutil.copy(base / name, job_dir / name)
    choice = rng.random()
    if choice < fine_share:
        (job_dir / "job.toml").write_bytes(toml_text(fine(rng)))
    elif choice < 0.6:
        (job_dir / "job.toml").write_bytes(toml_text(mutate_json(rng, BASE_JOB)))
    elif choice < 0.75:
        (job_dir / "job.toml").write_bytes(mutate_bytes(rng, toml_text(BASE_JOB)))
    elif choice < 0.9:
        data, suffix = mutate_mesh(rng, *_read(base / "part.obj"))
        (job_dir / f"part{suffix}").write_bytes(data)
        job = copy.deepcopy(BASE_JOB)
        job["object"]["mesh"] = f"part{suffix}"
        (job_dir / "job.toml").write_bytes(toml_text(job))
    else:
        (job_dir / "top.png").write_bytes(mutate_bytes(rng, (base / "top.png").read_bytes()))
        (job_dir / "job.toml").write_bytes(toml_text(BASE_JOB))


def _read(path: Path):
    from workbench.mesh.io import read_mesh

    return read_mesh(path)


def broken_design(rng, base: Path, target: Path) -> None:
    """A copy of the base design folder with one file broken (or none)."""
    shutil.copytree(base / "design", target)
    name = str(rng.choice(["design.json", "fixture.json", "print.png", "flat.obj", "decorated.obj", "owner.png", ""]))
    if not name:
        return
    path = target / name
    if name.endswith(".json") and rng.random() < 0.8:
        write_json(path, mutate_json(rng, json.loads(path.read_text())))
    elif rng.random() < 0.1:
        path.unlink()
    else:
        path.write_bytes(mutate_bytes(rng, path.read_bytes()))


@pytest.mark.parametrize("case", cases("pdf"))
def test_pdf(case, tmp_path, capsys, base):
    rng = rng_for("pdf", case)
    design = tmp_path / "design"
    broken_design(rng, base, design)
    out = tmp_path / "out.pdf"
    out.write_bytes(b"an earlier print")
    argv = ["pdf", design, "-o", out, "-q"]
    if rng.random() < 0.3:
        argv += ["--paper", str(rng.choice(["A4", "auto", "letter", "A9", "0x0", "1e9x1e9", "100x50", "nan x 3"]))]
    if rng.random() < 0.2:
        argv += [str(rng.choice(["--bleed-mm", "--margin-mm"])), str(rng.choice(["-1", "0", "5", "nan", "1e9"]))]
    if rng.random() < 0.2:
        profile = tmp_path / "printer.json"
        write_json(profile, mutate_json(rng, {"name": "p", "scale_x": 1.01, "scale_y": 0.99}))
        argv += ["--printer-profile", profile]
    if run(capsys, tmp_path, argv) == 0:
        assert out.read_bytes().startswith(b"%PDF")


@pytest.mark.parametrize("case", cases("board"))
def test_board(case, tmp_path, capsys, base):
    rng = rng_for("board", case)
    kind = str(rng.choice(["charuco", "printer-target", "fixture"]))
    out = tmp_path / "out" / "board.pdf"
    earlier_output(out.parent)
    argv = ["board", kind]
    if kind == "fixture":
        job_dir = tmp_path / "job"
        job_dir.mkdir()
        shutil.copy(base / "part.obj", job_dir / "part.obj")
        shutil.copy(base / "top.png", job_dir / "top.png")
        job = copy.deepcopy(BASE_JOB)
        if rng.random() < 0.7:
            job["fixture"] = mutate_json(
                rng, {"square_mm": 10, "squares": [8, 6], "marker_mm": 7, "dictionary": "DICT_5X5_250"}
            )
        (job_dir / "job.toml").write_bytes(toml_text(job))
        argv.append(job_dir / "job.toml")
    else:
        for flag, values in (
            ("--squares", ["7x5", "2x2", "3x3", "100x100", "axb", "0x5", "9x7"]),
            ("--square-mm", ["30", "0", "-1", "nan", "1e9", "0.001", "5"]),
            ("--marker-mm", ["22", "0", "40", "nan", "3"]),
            ("--dictionary", ["DICT_5X5_250", "DICT_4X4_50", "NOPE", "DICT_ARUCO_ORIGINAL"]),
            ("--first-id", ["0", "-1", "240", "1000000"]),
            ("--paper", ["A4", "A0", "letter", "A9", "10x10", "auto"]),
        ):
            if rng.random() < 0.35:
                argv += [flag, str(rng.choice(values))]
    if rng.random() < 0.15:
        profile = tmp_path / "printer.json"
        write_json(profile, mutate_json(rng, {"name": "p", "scale_x": 1.01, "scale_y": 0.99}))
        argv += ["--printer-profile", profile]
    if run(capsys, tmp_path, [*argv, "-o", out, "-q"]) == 0:
        assert out.read_bytes().startswith(b"%PDF") and out.with_suffix(".json").is_file()


@pytest.mark.parametrize("case", cases("render"))
def test_render(case, tmp_path, capsys, base):
    rng = rng_for("render", case)
    design = tmp_path / "design"
    broken_design(rng, base, design) if rng.random() < 0.5 else shutil.copytree(base / "design", design)
    out = tmp_path / "out" / "photo.png"
    earlier_output(out.parent)
    out.write_bytes(b"an earlier photo")
    how = rng.integers(4)
    if how == 0:
        argv = ["render", design, "--view", str(rng.choice(["top", "nope", "../top"]))]
    elif how == 1:
        cam = tmp_path / "camera.json"
        truth = json.loads((base / "photo.json").read_text())
        write_json(cam, mutate_json(rng, truth) if rng.random() < 0.8 else truth)
        argv = ["render", design, "--camera", cam]
    else:
        orbit = rng.choice(["0,60,250", "0,90,250", "0,60,0", "nan,1,2", "0,60,1e308", "1,2", "0,-90,250"])
        argv = ["render", design, "--orbit", str(orbit)]
        if rng.random() < 0.5:
            argv += ["--size", str(rng.choice(["64x48", "8x8", "7x7", "0x0", "axb", "20000x15000", "96x72"]))]
        if rng.random() < 0.2:
            argv += ["--fov-deg", str(rng.choice(["40", "0", "180", "nan", "1e-9"]))]
        if rng.random() < 0.2:
            prof = tmp_path / "profile.json"
            write_json(prof, mutate_json(rng, json.loads((base / "photo.json").read_text())))
            argv += ["--intrinsics", prof]
    argv += ["--supersample", str(rng.choice(["0", "9"])) if rng.random() < 0.1 else "1"]
    for flag, values in (
        ("--film-offset-mm", ["0.5,0", "nan,0", "1e9,1e9", "1"]),
        ("--blur-px", ["1", "-1", "nan", "100"]),
        ("--noise", ["3", "-3", "1e9"]),
        ("--light", ["0,0,1", "0,0,0", "nan,0,1"]),
        ("--jpeg-quality", ["90", "0", "101"]),
        ("--distortion=", ["-0.1,0,0,0,0", "1e9,0,0,0,0", "0,0"]),
    ):
        if rng.random() < 0.15:
            v = str(rng.choice(values))
            argv += [flag + v] if flag.endswith("=") else [flag, v]
    if rng.random() < 0.1:
        out = tmp_path / "out" / str(rng.choice(["photo.bmp", "photo.jpg", "sub/photo.png"]))
    if run(capsys, tmp_path, [*argv, "-o", out, "-q"]) == 0:
        assert out.is_file() and out.with_suffix(".json").is_file()


@pytest.mark.parametrize("case", cases("validate"))
def test_validate(case, tmp_path, capsys, base):
    rng = rng_for("validate", case)
    design = tmp_path / "design"
    what = rng.integers(4)
    broken_design(rng, base, design) if what == 0 else shutil.copytree(base / "design", design)
    photo = tmp_path / "photo.png"
    photo.write_bytes((base / "photo.png").read_bytes())
    if what == 1:
        photo.write_bytes(mutate_bytes(rng, photo.read_bytes()))
    profile = tmp_path / "profile.json"
    truth = json.loads((base / "photo.json").read_text())
    write_json(profile, mutate_json(rng, truth) if what == 2 else truth)
    out = tmp_path / "out"
    earlier_output(out)
    argv = ["validate", design, photo, "--camera", profile, "--out", out, "-q"]
    if what == 3:
        if rng.random() < 0.5:
            argv += ["--tolerance-mm", str(rng.choice(["0.5", "0", "-1", "nan", "1e308"]))]
        if rng.random() < 0.5:
            argv += ["--view", str(rng.choice(["top", "nope"]))]
        if rng.random() < 0.5:
            argv.insert(3, str(rng.choice([tmp_path, tmp_path / "missing.png", photo])))
    if run(capsys, tmp_path, argv) == 0:
        report = json.loads((out / "validation.json").read_text())
        assert all(e["verdict"] in ("PASS", "FAIL", "INVALID") and e["reason"] for e in report["photos"])
        assert (out / "earlier.txt").is_file()


@pytest.mark.parametrize("case", cases("calibrate"))
def test_calibrate(case, tmp_path, capsys, base):
    rng = rng_for("calibrate", case)
    scan = tmp_path / "scan.png"
    scan.write_bytes((CALIB / "regression" / "printer-target-scan-300dpi.png").read_bytes())
    if rng.random() < 0.3:
        scan.write_bytes(mutate_bytes(rng, scan.read_bytes()))
    board = tmp_path / "board.json"
    board_def = json.loads((CALIB / "boards" / "printer-target-A5.json").read_text())
    write_json(board, mutate_json(rng, board_def) if rng.random() < 0.4 else board_def)
    out = tmp_path / "out" / "profile.json"
    earlier_output(out.parent)
    what = rng.integers(3)
    if what == 0:
        prof = json.loads((CALIB / "printers" / "reference-laser.json").read_text())
        prof["board"]["file"] = "board.json"
        profile = tmp_path / "profile.json"
        write_json(profile, mutate_json(rng, prof) if rng.random() < 0.7 else prof)
        argv = ["calibrate", "check", profile, scan]
        if rng.random() < 0.2:
            argv += ["--tolerance-pct", str(rng.choice(["0.05", "0", "-1", "nan"]))]
    elif what == 1:
        dpi = str(rng.choice(["300", "600", "0", "-300", "nan", "1e9", "299"]))
        argv = ["calibrate", "printer", scan, "--board", board, "--dpi", dpi, "-o", out]
    else:
        photos = []
        for k in range(int(rng.integers(1, 4))):
            p = tmp_path / f"view{k}.png"
            p.write_bytes(mutate_bytes(rng, (base / "photo.png").read_bytes()) if rng.random() < 0.5 else b"")
            photos.append(p)
        argv = ["calibrate", "camera", *photos, "--board", board, "-o", out]
    run(capsys, tmp_path, [*argv, "-q"])


# --- outputs and signals (issue 25): every command, its output anywhere, interrupted anywhere ----

FAST_OUT, SLOW_OUT = 2, 100
FOLDER_COMMANDS = ("flatten", "design", "validate")


def output_cases() -> list:
    """(command, case): FAST_OUT per command by default, SLOW_OUT more marked slow."""
    out = []
    for command in COMMANDS:
        out += [pytest.param(command, i, id=f"{command}-{i}") for i in range(FAST_OUT)]
        out += [
            pytest.param(command, i, id=f"{command}-{i}", marks=pytest.mark.slow)
            for i in range(FAST_OUT, FAST_OUT + SLOW_OUT)
        ]
    return out


def command_inputs(command: str, root: Path, base: Path) -> tuple[list, list[Path]]:
    """A command that succeeds, without its output option, and the files it reads (copied under ``root``)."""
    job = root / "job"
    job.mkdir()
    for name in ("part.obj", "top.png", "job.toml"):
        shutil.copy(base / name, job / name)
    shutil.copytree(base / "design", root / "design")
    for name in ("photo.png", "photo.json"):
        shutil.copy(base / name, root / name)
    shutil.copy(CALIB / "regression" / "printer-target-scan-300dpi.png", root / "scan.png")
    shutil.copy(CALIB / "boards" / "printer-target-A5.json", root / "target.json")
    design_files = sorted(p for p in (root / "design").iterdir() if p.is_file())
    argv, inputs = {
        "flatten": (["flatten", job / "part.obj"], [job / "part.obj"]),
        "design": (["design", job / "job.toml"], [job / n for n in ("job.toml", "part.obj", "top.png")]),
        "pdf": (["pdf", root / "design"], design_files),
        "board": (["board", "charuco"], []),
        "render": (
            ["render", root / "design", "--orbit", "0,60,250", "--size", "64x48", "--supersample", "1"],
            design_files,
        ),
        "validate": (
            ["validate", root / "design", root / "photo.png", "--camera", root / "photo.json", "--jobs", "1"],
            [*design_files, root / "photo.png", root / "photo.json"],
        ),
        "calibrate": (
            ["calibrate", "printer", root / "scan.png", "--board", root / "target.json", "--dpi", "300"],
            [root / "scan.png", root / "target.json"],
        ),
        "suggest-views": (["suggest-views", job / "job.toml"], [job / n for n in ("job.toml", "part.obj", "top.png")]),
    }[command]
    return argv, inputs


def default_output(command: str, folder: Path) -> Path:
    names = {"pdf": "print.pdf", "board": "board.pdf", "render": "photo.png", "calibrate": "printer.json"}
    return folder / {**names, "suggest-views": "suggest.toml"}.get(command, "out")


def output_flag(command: str) -> str:
    return "--out" if command in FOLDER_COMMANDS else "-o"


def leftovers(root: Path) -> list[str]:
    return sorted(str(p) for p in root.rglob("*") if ".tmp-" in p.name or ".old-" in p.name)


def digests(paths) -> dict:
    import hashlib

    return {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in paths}


@pytest.mark.parametrize(("command", "case"), output_cases())
def test_output_anywhere(command, case, tmp_path, capsys, base, monkeypatch):
    """The output an input, '.', a symlink, a read-only earlier output, a long name, under a file, two of one name:
    the convention holds, no input changes, nothing temporary stays, and what is not ours is kept."""
    rng = np.random.default_rng([COMMANDS.index(command), case, 25])
    argv, inputs = command_inputs(command, tmp_path, base)
    out = default_output(command, tmp_path / "outs")
    kind = int(rng.integers(8))
    kept = target = None
    if kind == 1 and inputs:  # an input, or its folder
        target = inputs[int(rng.integers(len(inputs)))]
        out = target.parent if command in FOLDER_COMMANDS and rng.random() < 0.5 else target
    elif kind == 2:  # the current folder (folder commands), or a name in it
        here = tmp_path / "here"
        here.mkdir()
        kept = here / "user.txt"
        kept.write_text("the user's")
        monkeypatch.chdir(here)
        out = Path(".") if command in FOLDER_COMMANDS else Path(default_output(command, Path(".")).name)
    elif kind == 3:  # through a symlink to a folder holding a user's file
        real = tmp_path / "real"
        real.mkdir()
        kept = real / "user.txt"
        kept.write_text("the user's")
        (tmp_path / "link").symlink_to(real, target_is_directory=True)
        out = tmp_path / "link" if command in FOLDER_COMMANDS else default_output(command, tmp_path / "link")
    elif kind == 4:  # an earlier output made read-only
        assert main([str(a) for a in [*argv, output_flag(command), out, "-q"]]) == 0
        for p in out.rglob("*") if out.is_dir() else out.parent.glob(out.stem + ".*"):
            p.chmod(0o444)
    elif kind == 5:
        out = tmp_path / ("x" * int(rng.integers(240, 300)) + ("" if command in FOLDER_COMMANDS else out.suffix))
    elif kind == 6:
        (tmp_path / "afile").write_text("a file")
        out = tmp_path / "afile" / out.name
    elif kind == 7 and command in ("board", "calibrate"):  # two outputs of one name (board: PDF and definition)
        out = tmp_path / ("b.json" if command == "board" else "p.json")
        if command == "calibrate":
            argv = ["calibrate", "camera", tmp_path / "photo.png", "--board", tmp_path / "target.json"]
            inputs = [tmp_path / "photo.png", tmp_path / "target.json"]
            out = tmp_path / "cam.png"
    before = digests(inputs)
    status = run(capsys, tmp_path, [*argv, output_flag(command), out, "-q"])
    assert digests(inputs) == before, "an input changed"
    assert leftovers(tmp_path) == []
    if kept is not None:
        assert kept.read_text() == "the user's"
    if status == 0:
        assert (Path(out) / atomic_manifest()).is_file() if command in FOLDER_COMMANDS else Path(out).is_file()
    if out == target:
        assert status == 1


def atomic_manifest() -> str:
    from workbench.atomic import MANIFEST

    return MANIFEST


@pytest.mark.parametrize(("command", "case"), output_cases())
def test_signal_anywhere_in_the_write(command, case, tmp_path, capsys, base, monkeypatch):
    """SIGINT or SIGTERM at a random step of the write: either the earlier output as it was (exit 130, "nothing
    written") or the new one complete (exit 0, "which is complete"), and never a temporary left."""
    import os
    import signal

    from workbench import atomic

    rng = np.random.default_rng([COMMANDS.index(command), case, 26])
    argv, inputs = command_inputs(command, tmp_path, base)
    out = default_output(command, tmp_path / "outs")
    full = [str(a) for a in [*argv, output_flag(command), out, "-q"]]
    assert main(full) == 0  # an earlier output to keep
    before, digest = tree(tmp_path), digests(inputs)
    signum = signal.SIGINT if rng.random() < 0.5 else signal.SIGTERM
    at = int(rng.integers(1, 16))
    calls = []

    def step(fn):
        def wrapped(*a, **k):
            calls.append(fn)
            if len(calls) == at:
                os.kill(os.getpid(), signum)
            return fn(*a, **k)

        return wrapped

    monkeypatch.setattr(atomic, "_write_file", step(atomic._write_file))
    monkeypatch.setattr(atomic.os, "replace", step(atomic.os.replace))
    monkeypatch.setattr(atomic.os, "rename", step(atomic.os.rename))
    monkeypatch.setattr(atomic, "_link_or_copy", step(atomic._link_or_copy))
    capsys.readouterr()
    status = main([*full[:-1], "--quiet"])
    monkeypatch.undo()
    err = capsys.readouterr().err.strip().splitlines()
    assert "Traceback" not in "\n".join(err)
    err = [line for line in err if not line.startswith("warning: ")]  # pdf's resolution warning shows with -q
    assert leftovers(tmp_path) == [] and digests(inputs) == digest
    if at > len(calls):  # the write ended before the signal's turn
        assert status == 0 and err == []
    elif status == 130:
        assert err == [f"workbench {command}: interrupted; nothing written"]
        assert tree(tmp_path) == before
    else:
        assert status == 0 and len(err) == 1 and err[0].endswith("which is complete"), err
        # complete: the files of a full run, no fewer, no more
        names = set(tree(tmp_path))
        assert main(full) == 0 and set(tree(tmp_path)) == names

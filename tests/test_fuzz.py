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
# the store's readers (issue 41) after the first eight: each command's seeds stay as they were
COMMANDS = (
    "flatten",
    "design",
    "pdf",
    "board",
    "render",
    "validate",
    "calibrate",
    "suggest-views",
    "lot",
    "store export",
    "trend",
)
STORE_COMMANDS = ("lot", "store export", "trend")
FAST_STORE = 4  # a store command's case is a few milliseconds; the default run keeps a handful
CALIB = ROOT / "calib"


# slow cases that found a bug (an internal error: a store name too long to look up, ``~no-such-user/``, a
# damaged store's validation.json or text, a damaged store read through the driver's cursor), run by default too
REGRESSIONS = {"lot": (66, 115), "store export": (64,), "trend": (36, 197, 321)}


def cases(command: str, fast: int = FAST) -> list:
    """Case numbers: ``fast`` and the command's :data:`REGRESSIONS` in the default run, SLOW more marked slow."""
    again = REGRESSIONS.get(command, ())
    first = [pytest.param(i, id=f"{command}-{i}") for i in range(fast)]
    slow = [
        pytest.param(i, id=f"{command}-{i}", marks=() if i in again else pytest.mark.slow)
        for i in range(fast, fast + SLOW)
    ]
    return first + slow


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


def run(capsys, root: Path, argv: list[str], migrated: Path | None = None) -> int:
    """Run one command; check the convention; return its exit status.

    Any exception but SystemExit propagates and fails the test (a traceback for the user).
    ``migrated``: a store of an older schema, which any command brings up to date (checked by the caller).
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
        after = tree(root)
        if migrated is not None:
            before.pop(migrated.relative_to(root), None)
            after.pop(migrated.relative_to(root), None)
        assert after == before, "a failed run changed files"
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
    make_store(root / "store.db")
    return root


STORE_PARTS, STORE_LOTS = 30, ("lot-1", "lot-2")  # lot-1 the first 20 parts, lot-2 the last 10


def make_store(path: Path) -> Path:
    """A store of the current schema at ``path``: a simulated run's 30 parts of one design (two lots, two
    stations; the film drifting after part 20, so that the last parts FAIL) recorded through the store's own
    functions, and two printer calibration checks recorded by ``calibrate check --store``."""
    from trend_run import part_id, production_run, report_text

    from workbench.store.database import store_url
    from workbench.store.record import Recorder, record_validation, recorded_at, validation_rows

    url = store_url(str(path))
    run = production_run(seed=41, parts=STORE_PARTS, drift_mm=0.05, drift_after=20)
    for i in range(STORE_PARTS):
        lot = STORE_LOTS[0] if i < 20 else STORE_LOTS[1]
        rec = Recorder(url, part_id(i), lot, f"line-{1 + i % 2}", "qa")
        rows = validation_rows(report_text(run, i), path.parent, [], rec, recorded_at(1_700_000_000 + 60 * i))
        record_validation(rows, url)
    profile, scan = CALIB / "printers" / "reference-laser.json", CALIB / "regression" / "printer-target-scan-300dpi.png"
    for _ in range(2):
        assert main(["calibrate", "check", str(profile), str(scan), "--store", str(path), "-q"]) == 0
    return path


def make_version_1_store(path: Path, parts: int = 16) -> Path:
    """A store as the first release wrote it (schema version 1): ``parts`` parts of lot-1, no calibration table."""
    from sqlalchemy import create_engine, inspect
    from trend_run import DESIGN_SHA, part_id, production_run, report_text

    from workbench.store.schema import MIGRATIONS, schema_version, validations

    engine = create_engine(f"sqlite:///{path}")
    run = production_run(seed=5, parts=parts)
    with engine.begin() as conn:
        schema_version.create(conn)
        MIGRATIONS[0][2](conn)
        conn.execute(schema_version.insert().values(version=1, description=MIGRATIONS[0][1]))
        columns = {c["name"] for c in inspect(conn).get_columns("validations")} - {"id"}
        for i in range(parts):
            values = dict.fromkeys(columns)
            values.update(part_id=part_id(i), lot="lot-1", station="s", operator="o", software_version="v1")
            values.update(recorded_at=f"2026-01-01T00:{i:02d}:00Z", verdict="PASS", photos=1, photos_pass=1)
            values.update(photos_fail=0, photos_invalid=0, defects=0, out_dir="/x", tolerance_mm=0.5)
            values.update(validation_json=report_text(run, i), design_json_sha256=DESIGN_SHA)
            conn.execute(validations.insert().values(**values))
    engine.dispose()
    return path


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
FOLDER_COMMANDS = ("flatten", "design", "validate", "trend")


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
    shutil.copy(base / "store.db", root / "store.db")
    store = root / "store.db"
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
        "lot": (["lot", "lot-1", "--aql", "1.0", "--store", store], [store]),
        "store export": (["store", "export", store], [store]),
        "trend": (["trend", "--store", store], [store]),
    }[command]
    return argv, inputs


def default_output(command: str, folder: Path) -> Path:
    names = {"pdf": "print.pdf", "board": "board.pdf", "render": "photo.png", "calibrate": "printer.json"}
    names.update({"lot": "lot.html", "store export": "records.json"})
    return folder / {**names, "suggest-views": "suggest.toml"}.get(command, "out")


def output_flag(command: str) -> str:
    return "--report" if command == "lot" else "--out" if command in FOLDER_COMMANDS else "-o"


def quiet(command: str) -> list[str]:
    """The command's ``-q`` (the store's readers print their result and have none)."""
    return [] if command in STORE_COMMANDS else ["-q"]


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
        assert main([str(a) for a in [*argv, output_flag(command), out, *quiet(command)]]) == 0
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
    status = run(capsys, tmp_path, [*argv, output_flag(command), out, *quiet(command)])
    assert digests(inputs) == before, "an input changed"
    assert leftovers(tmp_path) == []
    if kept is not None:
        assert kept.read_text() == "the user's"
    if status == 0:
        assert (Path(out) / atomic_manifest()).is_file() if command in FOLDER_COMMANDS else Path(out).is_file()
    if out == target:
        assert status != 0


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
    full = [str(a) for a in [*argv, output_flag(command), out, *quiet(command)]]
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
    status = main([*full[:-1], "--quiet"] if quiet(command) else full)
    monkeypatch.undo()
    err = capsys.readouterr().err.strip().splitlines()
    assert "Traceback" not in "\n".join(err)
    # pdf's resolution warning shows with -q; the store's readers say what they wrote
    err = [line for line in err if not line.startswith(("warning: ", "wrote "))]
    assert leftovers(tmp_path) == [] and digests(inputs) == digest
    if at > len(calls):  # the write ended before the signal's turn
        assert status == 0 and err == []
    elif status == 130:
        assert err == [f"workbench {command.split()[0]}: interrupted; nothing written"]
        assert tree(tmp_path) == before
    else:
        assert status == 0 and len(err) == 1 and err[0].endswith("which is complete"), err
        # complete: the files of a full run, no fewer, no more
        names = set(tree(tmp_path))
        assert main(full) == 0 and set(tree(tmp_path)) == names


# --- the store's readers (issue 41): lot, store export and trend on a broken store, options, output ------------

# the store as given: what it is (a copy of the base store unless said), and whether the command may write it
STORE_KINDS = (
    "fine",
    "fine",
    "fine",
    "folder",
    "fifo",
    "device",
    "dangling-link",
    "looping-link",
    "truncated",
    "bytes-broken",
    "garbage",
    "empty",
    "newer-schema",
    "older-schema",
    "unreachable",
    "url-garbage",
    "environment-garbage",
    "missing",
)
URL_GARBAGE = (
    "sqlite://",
    "sqlite:///:memory:",
    "mysql://u@127.0.0.1:1/x",
    "nope://x",
    "postgresql://[::1",
    "postgresql://u:secret@127.0.0.1:99999/x",
    "://",
    " ",
    "~no-such-user/store.db",
    "sqlite:////nonexistent/folder/s.db",
    "x" * 5000,
)


def drawn_store(rng, base: Path, root: Path) -> tuple[str | None, str, Path | None]:
    """The store a case gives: (its text, or None for WORKBENCH_STORE's own value; its kind; the file behind it
    that must stay as it was, or None)."""
    import os
    import sqlite3

    kind = str(rng.choice(STORE_KINDS))
    path = root / "store.db"
    if kind in ("fine", "truncated", "bytes-broken", "newer-schema"):
        shutil.copy(base / "store.db", path)
    if kind == "folder":
        path.mkdir()
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "device":
        return str(rng.choice(["/dev/null", "/dev/zero", "/dev/full"])), kind, None
    elif kind == "dangling-link":
        path.symlink_to(root / "gone.db")
    elif kind == "looping-link":
        path.symlink_to(root / "loop.db")
        (root / "loop.db").symlink_to(path)
    elif kind == "truncated":
        data = path.read_bytes()
        path.write_bytes(data[: int(rng.integers(len(data)))])
    elif kind == "bytes-broken":
        path.write_bytes(mutate_bytes(rng, path.read_bytes()))
    elif kind == "garbage":
        path.write_bytes(rng.integers(0, 256, int(rng.integers(1, 20000))).astype(np.uint8).tobytes())
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "newer-schema":
        with sqlite3.connect(path) as conn:
            conn.execute("insert into schema_version (version, description) values (99, 'a later workbench')")
        conn.close()
    elif kind == "older-schema":
        make_version_1_store(path)
    elif kind == "unreachable":
        return "postgresql://u@127.0.0.1:1/x", kind, None
    elif kind == "url-garbage":
        return str(rng.choice(URL_GARBAGE)), kind, None
    elif kind == "environment-garbage":
        return None, kind, None
    return str(path), kind, (path if path.is_file() and not path.is_symlink() else None)


def drawn_output(rng, root: Path, name: str, folder: bool) -> tuple[Path | None, bool]:
    """Where a case writes (None: no output option) and whether it must fail (an output that is the store)."""
    import os

    kind = int(rng.integers(11))
    outs = root / "outs"
    earlier_output(outs)
    if kind <= 2:
        return None, False
    if kind == 3:
        return outs / name, False
    if kind == 4:  # an earlier output, or a file where a folder is wanted
        if folder:
            return outs / "earlier.txt", True
        (outs / name).write_text("an earlier output")
        return outs / name, False
    if kind == 5:  # a folder: where a file is wanted, or a folder holding a user's file
        return outs, not folder
    if kind == 6:  # a link to the store
        (root / f"link-{name}").symlink_to(root / "store.db")
        return root / f"link-{name}", False
    if kind == 7:
        return Path(str(rng.choice(["/dev/null", "/dev/full", "/dev/stdout"]))), True
    if kind == 8:
        os.mkfifo(outs / name)
        return outs / name, True
    if kind == 9:  # the store itself
        return root / "store.db", True
    (root / "afile").write_text("a file")
    return root / "afile" / name, True


def store_case(rng, base: Path, root: Path, monkeypatch, command: str) -> tuple[list, Path | None, str]:
    """The store and its environment for one case: (the argv's store part, the store file, its kind)."""
    text, kind, store = drawn_store(rng, base, root)
    garbage = str(rng.choice(["", " ", "nope://x", "/nonexistent/s.db", str(root), "sqlite://"]))
    monkeypatch.delenv("WORKBENCH_STORE", raising=False)
    if kind == "environment-garbage":
        monkeypatch.setenv("WORKBENCH_STORE", garbage)
    if command == "store export":
        return [text if text is not None else garbage], store, kind
    if text is not None and rng.random() < 0.2:  # the store from the environment
        monkeypatch.setenv("WORKBENCH_STORE", text)
        return [], store, kind
    return ([] if text is None else ["--store", text]), store, kind


def devices() -> list[str]:
    import os

    return sorted(os.listdir("/dev"))


def store_run(capsys, root: Path, argv: list, store: Path | None, kind: str, outputs: list[Path]) -> int:
    """Run a store reader: the convention (:func:`run`), and the store as it was (an older schema's store may be
    brought up to date), nothing but ``outputs`` changed, nothing new in /dev."""
    before, digest, dev = tree(root), (store.read_bytes() if store is not None else None), devices()
    status = run(capsys, root, argv, store if kind == "older-schema" else None)
    assert devices() == dev, "a file was made in /dev"
    if store is not None and kind != "older-schema":
        assert store.read_bytes() == digest, "the store changed"
    if store is not None and kind == "older-schema" and store.read_bytes() != digest:
        from sqlalchemy import create_engine, select

        from workbench.store.schema import LATEST, schema_version

        engine = create_engine(f"sqlite:///{store}")
        with engine.connect() as conn:
            assert conn.execute(select(schema_version.c.version)).scalars().all() == list(range(1, LATEST + 1))
        engine.dispose()
    after = tree(root)
    declared = [Path(o).absolute() for o in outputs]
    changed = [
        p
        for p in set(before) | set(after)
        if before.get(p) != after.get(p)
        and (store is None or root / p != store)
        and not any(root / p == d or d in (root / p).parents for d in declared)
    ]
    assert changed == [], f"changed outside the outputs: {changed}"
    return status


AQLS = ("1.0", "0.65", "2.5", "0.010", "1000", "0.011", "1001", "0", "-1", "nan", "x", "1e0", "", "0.1 ")
LOT_NAMES = ("lot-1", "lot-2", "lot-3", "", "'; drop table validations; --", "LOT-1", "lot-1 ", "é" * 300)


@pytest.mark.parametrize("case", cases("lot", FAST_STORE))
def test_lot(case, tmp_path, capsys, base, monkeypatch):
    rng = rng_for("lot", case)
    store_argv, store, kind = store_case(rng, base, tmp_path, monkeypatch, "lot")
    argv = ["lot", str(rng.choice(LOT_NAMES)) if rng.random() < 0.3 else "lot-1", *store_argv]
    argv += ["--aql", str(rng.choice(AQLS)) if rng.random() < 0.4 else "1.0"]
    if rng.random() < 0.3:
        argv += ["--level", str(rng.choice(["S-1", "S-4", "I", "II", "III", "IV", "", "ii"]))]
    if rng.random() < 0.3:
        sizes = ["0", "-5", "1", "2", "13", "20", "1e12", "1000000000000", "1000000000001", "x", "nan", "1.5"]
        argv += ["--lot-size", str(rng.choice(sizes))]
    if rng.random() < 0.3:
        argv.append("--allow-reduced")
    if rng.random() < 0.3:
        argv.append("--json")
    outputs, must_fail = [], False
    for _ in range(int(rng.integers(0, 3))):
        name = str(rng.choice(["lot.html", "lot.pdf", "lot.HTML", "lot.txt", "lot"]))
        out, fails = drawn_output(rng, tmp_path, name, folder=False)
        if out is not None:
            argv += ["--report", out]
            outputs.append(out)
            must_fail = must_fail or fails
    status = store_run(capsys, tmp_path, argv, store, kind, outputs)
    assert not (must_fail and status == 0), "an output that cannot be written was accepted"
    if status == 0:
        assert all(Path(o).is_file() for o in outputs if not str(o).startswith("/dev/"))


@pytest.mark.parametrize("case", cases("store export", FAST_STORE))
def test_store_export(case, tmp_path, capsys, base, monkeypatch):
    rng = rng_for("store export", case)
    store_argv, store, kind = store_case(rng, base, tmp_path, monkeypatch, "store export")
    argv = ["store", "export", *store_argv]
    if rng.random() < 0.4:
        argv += ["--format", str(rng.choice(["csv", "json", "xml", "", "CSV"]))]
    if rng.random() < 0.4:
        argv += ["--lot", str(rng.choice(LOT_NAMES))]
    out, must_fail = drawn_output(rng, tmp_path, str(rng.choice(["records.json", "records.csv"])), folder=False)
    if out is not None:
        argv += [str(rng.choice(["-o", "--out"])), out]
    status = store_run(capsys, tmp_path, argv, store, kind, [out] if out is not None else [])
    assert not (must_fail and status == 0), "an output that cannot be written was accepted"
    if status == 0 and out is not None:
        assert str(out).startswith("/dev/") or out.is_file()


@pytest.mark.parametrize("case", cases("trend", FAST_STORE))
def test_trend(case, tmp_path, capsys, base, monkeypatch):
    rng = rng_for("trend", case)
    store_argv, store, kind = store_case(rng, base, tmp_path, monkeypatch, "trend")
    argv = ["trend", *store_argv]
    options = {
        "--design": ["sim", "dddddd", "ddddd", "d" * 64, "x", "", "%", "_"],
        "--station": ["line-1", "line-2", "nope", ""],
        "--since": ["2023-11-14", "2023-11-14T22:30:00Z", "garbage", "2023-13-45", "9999-12-31", "0001-01-01", "-1"],
        "--baseline-parts": ["0", "1", "2", "15", "30", "31", "1e9", "-3", "x", "1000000000", "nan"],
        "--rules": ["1,2", "0", "9", "x", "", ",", "1,,2", "1.5", "8,1", "-1", "1e0", "99999999999999999999"],
        "--horizon": ["-1", "0", "nan", "inf", "1e9", "1e10", "x", "2.5"],
        "--camera": ["reference-laser", "nope", ""],
    }
    for flag, values in options.items():
        if rng.random() < 0.2:
            argv += [flag, str(rng.choice(values))]
    for flag in ("--every-signal", "--calibration", "--json"):
        if rng.random() < 0.25:
            argv.append(flag)
    out, must_fail = drawn_output(rng, tmp_path, "trend", folder=True)
    if out is not None:
        argv += ["--out", out]
    status = store_run(capsys, tmp_path, argv, store, kind, [out] if out is not None else [])
    assert not (must_fail and status == 0), "an output that cannot be written was accepted"
    if status == 0 and out is not None:
        assert (out / "trend.html").is_file() and (tmp_path / "outs" / "earlier.txt").is_file()


@pytest.mark.parametrize("command", STORE_COMMANDS)
@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_a_store_that_is_not_a_file_is_never_opened(command, kind, tmp_path, capsys):
    """SQLite opened a named pipe or a device as a store ("disk I/O error", or /dev/zero read as an empty
    database): now it is refused by its kind before it is opened."""
    import os

    store = Path("/dev/zero") if kind == "device" else tmp_path / "pipe.db"
    if kind == "fifo":
        os.mkfifo(store)
    argv = {"lot": ["lot", "lot-1", "--aql", "1.0", "--store"], "store export": ["store", "export"]}
    before = devices()
    assert run(capsys, tmp_path, [*argv.get(command, ["trend", "--store"]), store]) == 1
    said = "a character device" if kind == "device" else "a named pipe"
    assert capsys.readouterr().err == "" and devices() == before
    assert main([*argv.get(command, ["trend", "--store"]), str(store)]) == 1
    assert f"{store} is {said}, not a store" in capsys.readouterr().err


def test_export_refuses_the_store_as_its_output(tmp_path, capsys, base):
    """``store export STORE -o STORE`` replaced the store with its own export."""
    store = tmp_path / "store.db"
    shutil.copy(base / "store.db", store)
    data = store.read_bytes()
    assert main(["store", "export", str(store), "-o", str(store)]) == 1
    assert "is an input of this command" in capsys.readouterr().err and store.read_bytes() == data


FAST_CHECK, SLOW_CHECK = 2, 100  # calibrate check measures a scan (half a second) before it records


@pytest.mark.parametrize(
    "case",
    [pytest.param(i, id=f"check-store-{i}") for i in range(FAST_CHECK)]
    + [
        pytest.param(i, id=f"check-store-{i}", marks=pytest.mark.slow)
        for i in range(FAST_CHECK, FAST_CHECK + SLOW_CHECK)
    ],
)
def test_calibrate_check_store(case, tmp_path, capsys, base, monkeypatch):
    """``calibrate check --store`` on the stores the readers get: a check is recorded whole (its verdict OK with
    exit 0, DRIFT with exit 1) in a store it can write, or nothing is written and the store stays as it was."""
    import sqlite3

    rng = np.random.default_rng([COMMANDS.index("calibrate"), case, 41])
    store_argv, _, kind = store_case(rng, base, tmp_path, monkeypatch, "calibrate")
    scan = tmp_path / "scan.png"
    scan.write_bytes((CALIB / "regression" / "printer-target-scan-300dpi.png").read_bytes())
    if rng.random() < 0.2:
        scan.write_bytes(mutate_bytes(rng, scan.read_bytes()))
    argv = ["calibrate", "check", CALIB / "printers" / "reference-laser.json", scan, *store_argv, "-q"]
    if rng.random() < 0.4:
        argv += ["--tolerance-pct", str(rng.choice(["0.00001", "0.05", "nan", "-1"]))]
    path = tmp_path / "store.db"
    data = path.read_bytes() if path.is_file() and not path.is_symlink() else None
    before, dev = tree(tmp_path), devices()
    status = run(capsys, tmp_path, argv, migrated=path)  # the store is this command's output
    assert devices() == dev, "a file was made in /dev"
    # the store, or what its dangling link points to (made as ``>`` in a shell would make it)
    ours = {Path("store.db"), Path("gone.db")}
    assert {k: v for k, v in tree(tmp_path).items() if k not in ours} == {
        k: v for k, v in before.items() if k not in ours
    }
    if kind not in ("fine", "older-schema", "missing") or not path.is_file() or path.read_bytes() == data:
        return  # (a damaged store SQLite still reads may take a record too)
    with sqlite3.connect(path) as conn:
        verdict = conn.execute("select verdict from calibrations order by id desc limit 1").fetchone()[0]
    conn.close()
    assert verdict == ("OK" if status == 0 else "DRIFT"), (status, verdict)

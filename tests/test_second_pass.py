"""Issue 25: never destroy an input, never a silent wrong result.

One test per finding: outputs that are inputs, ``--out`` edge cases (``.``, a symlink, a
read-only earlier output, a name over 255 bytes), signals during the write, stale files,
results that are legal but absurd (a warning, an error with ``--strict``), tracebacks on
absurd values and errors that name no file or option.
"""

from __future__ import annotations

import copy
import json
import os
import shutil
import signal
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import ROOT, grid_corners
from test_fuzz import BASE_JOB, make_base, toml_text

from workbench import atomic
from workbench.cli import main

CALIB = ROOT / "calib"
SCAN = CALIB / "regression" / "printer-target-scan-300dpi.png"
TARGET = CALIB / "boards" / "printer-target-A5.json"


def tree(path: Path) -> dict:
    return {p.relative_to(path): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


def leftovers(path: Path) -> list[str]:
    """Temporary or backup files and folders of a write, anywhere under ``path``."""
    return sorted(str(p) for p in path.rglob("*") if ".tmp-" in p.name or ".old-" in p.name)


def one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """The fuzz suite's small job (60 x 40 mm lid, one 320 x 240 view, 30 dpi), its design and a photo."""
    return make_base(tmp_path_factory.mktemp("second-pass"))


@pytest.fixture
def work(base, tmp_path):
    """A copy of the job, its design and the photo in a fresh folder."""
    for name in ("job.toml", "part.obj", "top.png", "photo.png", "photo.json"):
        shutil.copy(base / name, tmp_path / name)
    shutil.copytree(base / "design", tmp_path / "design")
    return tmp_path


def run(argv) -> int:
    return main([str(a) for a in argv])


# --- 1. an output that is an input --------------------------------------------------------------


@pytest.mark.parametrize(
    "argv",
    [
        ["pdf", "{d}", "-o", "{d}/print.png"],
        ["pdf", "{d}", "-o", "{d}/design.json"],
        ["render", "{d}", "--orbit", "0,60,250", "--size", "64x48", "-o", "{d}/print.png"],
        ["render", "{d}", "--orbit", "0,60,250", "--size", "64x48", "-o", "{d}/../design/flat.png"],  # flat.json
        ["validate", "{d}", "{w}/photo.png", "--camera", "{w}/photo.json", "--out", "{d}"],
        ["design", "{w}/job.toml", "--out", "{w}/part.obj"],
    ],
    ids=["pdf-print", "pdf-design-json", "render-print", "render-json-beside", "validate-into-design", "design-mesh"],
)
def test_an_output_that_is_an_input_is_refused_before_any_work(work, capsys, argv):
    (work / "design" / "flat.json").write_text("a file of the design folder's that render's truth would replace")
    manifest = work / "design" / atomic.MANIFEST
    manifest.write_text(manifest.read_text() + "flat.json\n")
    before = tree(work)
    args = [a.replace("{d}", str(work / "design")).replace("{w}", str(work)) for a in argv]
    assert run(args) == 1
    line = one_line(capsys)
    assert "is an input" in line or "is a file" in line, line
    assert tree(work) == before


@pytest.mark.parametrize(
    "argv",
    [
        ["board", "charuco", "-o", "{w}/b.json"],
        ["calibrate", "camera", "{w}/photo.png", "--board", str(TARGET), "-o", "{w}/cam.png"],
    ],
    ids=["board-pdf-and-definition", "calibrate-profile-and-picture"],
)
def test_two_outputs_of_one_name_are_refused(work, capsys, argv):
    before = tree(work)
    assert run([a.replace("{w}", str(work)) for a in argv]) == 1
    assert "two outputs of this command would share this name" in one_line(capsys)
    assert tree(work) == before


def test_an_output_through_a_symlink_onto_an_input_is_refused(work, capsys):
    (work / "alias.png").symlink_to(work / "design" / "print.png")
    before = tree(work)
    assert run(["pdf", work / "design", "-o", work / "alias.png"]) == 1
    assert "alias.png: is an input of this command" in one_line(capsys)
    assert tree(work) == before


# --- 2. --out edge cases ------------------------------------------------------------------------


def test_out_dot_writes_into_the_current_folder_and_keeps_what_is_not_ours(work, monkeypatch):
    job = work / "job"
    job.mkdir()
    for name in ("job.toml", "part.obj", "top.png"):
        shutil.move(work / name, job / name)
    (job / "notes.txt").write_text("the user's")
    monkeypatch.chdir(job)
    assert run(["design", "job.toml", "--out", ".", "-q"]) == 0
    assert run(["design", "job.toml", "--out", ".", "-q"]) == 0  # and again over its own output
    names = {p.name for p in job.iterdir()}
    assert {"job.toml", "part.obj", "top.png", "notes.txt", "print.png", "design.json", atomic.MANIFEST} <= names
    assert (job / "notes.txt").read_text() == "the user's"
    assert json.loads((job / "design.json").read_text())["job"]["file"] == "job.toml"
    assert leftovers(work) == []


def test_out_through_a_symlink_keeps_the_link_and_the_targets_other_files(work):
    target = work / "real"
    target.mkdir()
    (target / "mine.txt").write_text("kept")
    link = work / "link"
    link.symlink_to(target, target_is_directory=True)
    assert run(["flatten", work / "part.obj", "--out", link, "-q"]) == 0
    assert link.is_symlink() and Path(os.readlink(link)) == target
    assert {p.name for p in target.iterdir()} == {
        "mine.txt",
        "flat.obj",
        "flatten.json",
        "flatten.png",
        atomic.MANIFEST,
    }
    assert leftovers(work) == []


def test_a_read_only_earlier_output_is_replaced_without_a_copy_left_behind(work):
    out = work / "out"
    assert run(["flatten", work / "part.obj", "--out", out, "-q"]) == 0
    for p in out.iterdir():
        p.chmod(0o444)
    assert run(["flatten", work / "part.obj", "--out", out, "--scale", "width=50", "-q"]) == 0
    assert json.loads((out / "flatten.json").read_text())["width_mm"] == pytest.approx(50.0)
    assert leftovers(work) == []


LONG = "n" * 300


@pytest.mark.parametrize(
    "argv",
    [
        ["flatten", "{w}/part.obj", "--out", "{w}/" + LONG],
        ["design", "{w}/job.toml", "--out", "{w}/" + LONG],
        ["pdf", "{w}/design", "-o", "{w}/" + LONG + ".pdf"],
        ["board", "charuco", "-o", "{w}/" + LONG + ".pdf"],
        ["render", "{w}/design", "--orbit", "0,60,250", "--size", "64x48", "-o", "{w}/" + LONG + ".png"],
        ["validate", "{w}/design", "{w}/photo.png", "--camera", "{w}/photo.json", "--out", "{w}/" + LONG],
        ["calibrate", "printer", str(SCAN), "--board", str(TARGET), "--dpi", "300", "-o", "{w}/" + LONG + ".json"],
    ],
    ids=lambda a: a[0],
)
def test_an_output_name_over_255_bytes_is_one_line_before_any_work(work, capsys, argv):
    before = tree(work)
    assert run([a.replace("{w}", str(work)) for a in argv]) == 1
    assert "a file name takes at most" in one_line(capsys)
    assert tree(work) == before


# --- 3. signals ---------------------------------------------------------------------------------


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize("at", [1, 3])
def test_a_signal_while_writing_leaves_the_earlier_output_and_no_temporary(work, capsys, monkeypatch, signum, at):
    out = work / "out"
    assert run(["flatten", work / "part.obj", "--out", out, "-q"]) == 0
    before = tree(work)
    write, calls = atomic._write_file, []

    def interrupted(path, data):
        calls.append(path)
        if len(calls) == at:
            os.kill(os.getpid(), signum)
        write(path, data)

    monkeypatch.setattr(atomic, "_write_file", interrupted)
    assert run(["flatten", work / "part.obj", "--out", out, "--scale", "width=50", "-q"]) == 130
    assert one_line(capsys) == "workbench flatten: interrupted; nothing written"
    assert tree(work) == before and leftovers(work) == []


def test_a_signal_during_the_renames_ends_with_the_output_complete(work, capsys, monkeypatch):
    out = work / "out"
    assert run(["flatten", work / "part.obj", "--out", out, "-q"]) == 0
    replace, calls = atomic.os.replace, []

    def interrupted(src, dst):
        calls.append(dst)
        if len(calls) == 1:
            os.kill(os.getpid(), signal.SIGINT)
        replace(src, dst)

    monkeypatch.setattr(atomic.os, "replace", interrupted)
    assert run(["flatten", work / "part.obj", "--out", out, "--scale", "width=50", "-q"]) == 0
    assert one_line(capsys) == f"workbench flatten: interrupted after writing {out}, which is complete"
    assert json.loads((out / "flatten.json").read_text())["width_mm"] == pytest.approx(50.0)
    assert leftovers(work) == []


def test_a_signal_after_the_write_is_reported_as_success(work, capsys, monkeypatch):
    from workbench.commands import flatten

    out = work / "out.pdf"
    write_folder = flatten.write_folder

    def then_interrupted(*a, **k):
        write_folder(*a, **k)
        os.kill(os.getpid(), signal.SIGTERM)  # during the progress lines that follow

    monkeypatch.setattr(flatten, "write_folder", then_interrupted)
    assert run(["flatten", work / "part.obj", "--out", out]) == 0
    assert (
        capsys.readouterr().err.strip().splitlines()[-1].endswith(f"interrupted after writing {out}, which is complete")
    )
    assert (out / "flat.obj").is_file() and leftovers(work) == []


def test_signal_handlers_are_put_back(work):
    before = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)
    assert run(["flatten", work / "part.obj", "--out", work / "o", "-q"]) == 0
    assert (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)) == before


# --- 4. stale files -----------------------------------------------------------------------------


def test_an_output_folder_holds_exactly_what_its_last_run_wrote(work):
    out = work / "validation"
    shutil.copy(work / "photo.png", work / "first.png")
    shutil.copy(work / "photo.png", work / "second.png")
    (work / "keep").mkdir()
    common = ["--camera", work / "photo.json", "--out", out, "--jobs", "1", "-q"]
    assert run(["validate", work / "design", work / "first.png", *common]) == 0
    assert any(p.name.startswith("first") for p in out.iterdir())
    (out / "my-notes.txt").write_text("not ours: kept")
    assert run(["validate", work / "design", work / "second.png", *common]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert not [n for n in names if n.startswith("first")], names
    assert "my-notes.txt" in names and any(n.startswith("second") for n in names)
    listed = set(atomic.folder_manifest(out))
    assert listed == set(names) - {"my-notes.txt", atomic.MANIFEST}
    report = json.loads((out / "validation.json").read_text())
    assert [Path(e["photo"]).name for e in report["photos"]] == ["second.png"]


def test_a_design_rerun_keeps_the_validation_folder_inside_it(work):
    d = work / "design"
    (d / "validation").mkdir()
    (d / "validation" / "validation.json").write_text("{}")
    assert run(["design", work / "job.toml", "--out", d, "-q"]) == 0
    assert (d / "validation" / "validation.json").read_text() == "{}"


# --- 5. silent wrong results: warnings, --strict errors -----------------------------------------


def write_job(folder: Path, job: dict) -> Path:
    path = folder / "job.toml"
    path.write_bytes(toml_text(job))
    return path


def design_warnings(capsys, job: Path, out: Path) -> list[str]:
    """The warnings of a design that succeeds without --strict and fails with it, writing nothing."""
    capsys.readouterr()
    assert run(["design", job, "--out", out]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning: ")]
    info = json.loads((out / "design.json").read_text())
    assert set(f"warning: {w}" for w in info["warnings"]) <= set(warnings)
    strict = out.parent / "strict"
    assert run(["design", job, "--out", strict, "--strict", "-q"]) == 1
    assert "(--strict)" in one_line(capsys) and not strict.exists()
    return info["warnings"]


def test_films_whose_faces_meet_only_at_corners_warn(work, capsys):
    from workbench.mesh.io import read_mesh

    V, F = read_mesh(work / "part.obj")
    nx = 10  # the part is a 10 x 8 grid: a face's lowest vertex is its quad's corner
    a = F.min(axis=1)
    black = (a % nx + a // nx) % 2 == 0
    (work / "black.txt").write_text(" ".join(map(str, np.flatnonzero(black))))
    (work / "white.txt").write_text(" ".join(map(str, np.flatnonzero(~black))))
    job = copy.deepcopy(BASE_JOB)
    job["films"] = [{"name": "black", "faces": "black.txt"}, {"name": "white", "faces": "white.txt"}]
    warnings = design_warnings(capsys, write_job(work, job), work / "out")
    kept = [w for w in warnings if "keeps" in w]
    assert len(kept) == 2 and all("meet only at corners" in w for w in kept), warnings
    assert any("is on no film" in w for w in warnings), warnings


def test_a_film_that_leaves_part_of_the_surface_bare_warns(work, capsys):
    from workbench.mesh.io import read_mesh

    V, F = read_mesh(work / "part.obj")
    left = np.flatnonzero(V[F].mean(axis=1)[:, 0] < 10.0)  # 2/3 of the 60 mm lid
    (work / "left.txt").write_text(" ".join(map(str, left)))
    job = copy.deepcopy(BASE_JOB)
    job["films"] = [{"name": "left", "faces": "left.txt", "outline": "free"}]
    warnings = design_warnings(capsys, write_job(work, job), work / "out")
    bare = [w for w in warnings if "is on no film" in w]
    assert len(bare) == 1 and float(bare[0].split(" %")[0]) == pytest.approx(100 / 3, abs=6), warnings


def test_a_view_image_too_small_for_the_print_warns(work, capsys):
    cv2.imwrite(str(work / "tiny.png"), np.full((1, 1, 3), 128, np.uint8))
    job = copy.deepcopy(BASE_JOB)
    job["views"][0]["image"] = "tiny.png"
    warnings = design_warnings(capsys, write_job(work, job), work / "out")
    assert warnings[0].startswith("view 'top' paints 98.0 % of the print at 0.28 dpi")
    # (one pixel is one flat colour too: issue 41's warning of a view image with no picture)
    assert len(warnings) == 2 and "views[0].image is one flat colour" in warnings[1]


def test_a_view_with_an_absurd_focal_length_warns(work, capsys):
    job = copy.deepcopy(BASE_JOB)
    view = {"name": "top", "image": "top.png", "fx": 1e-300, "fy": 1e-300, "cx": 159.5, "cy": 119.5}
    job["views"] = [{**view, "rotation": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "translation": [0, 0, 200]}]
    warnings = design_warnings(capsys, write_job(work, job), work / "out")
    assert len(warnings) == 1 and "its image is too small for the print" in warnings[0], warnings


def test_a_print_at_one_dpi_warns(work, capsys):
    job = copy.deepcopy(BASE_JOB)
    job["print"]["dpi"] = 1
    warnings = design_warnings(capsys, write_job(work, job), work / "out")
    assert warnings[0] == "the print's 1 dpi makes pixels of 25 mm: below 10 dpi no detail shows", warnings


def test_the_transparent_part_of_an_rgba_view_prints_in_the_background_colour(work):
    rgba = np.zeros((240, 320, 4), np.uint8)
    rgba[:, :160] = (200, 50, 50, 255)  # BGRA: the left half opaque blue, the right half transparent black
    cv2.imwrite(str(work / "rgba.png"), rgba)
    job = copy.deepcopy(BASE_JOB)
    job["views"][0]["image"] = "rgba.png"
    job["print"]["background"] = "#00ff00"
    assert run(["design", write_job(work, job), "--out", work / "out", "-q"]) == 0
    rgb = cv2.cvtColor(cv2.imread(str(work / "out" / "print.png")), cv2.COLOR_BGR2RGB)
    row = rgb[rgb.shape[0] // 2]
    assert (row[3] == [50, 50, 200]).all() and (row[-4] == [0, 255, 0]).all()
    view = cv2.imread(str(work / "out" / "view-top.png"), cv2.IMREAD_UNCHANGED)
    assert view.shape == (240, 320, 3) and (view[0, -1] == [0, 255, 0]).all()  # validate sees what design used


def test_flatten_of_a_regular_grid_picks_its_corners(tmp_path):
    from workbench.mesh.io import format_obj

    nx, ny = 11, 21
    x, y = np.meshgrid(np.linspace(0, 60, nx), np.linspace(0, 40, ny))
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(nx * ny)])
    F = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a = j * nx + i
            F += [[a, a + 1, a + nx + 1], [a, a + nx + 1, a + nx]]
    (tmp_path / "plate.obj").write_bytes(format_obj(V, np.array(F)))
    assert run(["flatten", tmp_path / "plate.obj", "--out", tmp_path / "out", "-q"]) == 0
    info = json.loads((tmp_path / "out" / "flatten.json").read_text())
    assert set(info["corners"]) == set(grid_corners(nx, ny))
    assert (info["width_mm"], info["height_mm"]) == pytest.approx((60.0, 40.0), abs=1e-6)
    assert info["stretch"]["min"] == pytest.approx(1.0, abs=1e-6) and info["stretch"]["max"] == pytest.approx(1.0)


def test_choose_corners_on_every_regular_grid():
    from workbench.conformal.corners import choose_corners
    from workbench.mesh.topology import boundary_loops

    wrong = []
    for nx in range(3, 27):
        for ny in range(3, 27):
            x, y = np.meshgrid(np.linspace(0, 60, nx), np.linspace(0, 40, ny))
            V = np.column_stack([x.ravel(), y.ravel(), np.zeros(nx * ny)])
            a = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
            F = np.concatenate([np.stack([a, a + 1, a + nx + 1], 1), np.stack([a, a + nx + 1, a + nx], 1)])
            corners, _ = choose_corners(V, F, boundary_loops(F)[0])
            if set(corners.tolist()) != set(grid_corners(nx, ny)):
                wrong.append((nx, ny))
    assert wrong == []  # was 18 of 576 (101 in the sweep of other sizes)


def scaled_target(path: Path, factor: float) -> Path:
    """The printer target's definition with every length times ``factor`` (a definition of another target)."""
    d = json.loads(TARGET.read_text())
    d["square_mm"] *= factor
    d["marker_mm"] *= factor
    d["charuco_corners"]["board_mm"] = (np.asarray(d["charuco_corners"]["board_mm"]) * factor).tolist()
    d["markers"]["corners_board_mm"] = (np.asarray(d["markers"]["corners_board_mm"]) * factor).tolist()
    path.write_text(json.dumps(d))
    return path


def test_calibrate_printer_warns_of_a_scale_no_printer_has_and_strict_refuses_it(tmp_path, capsys):
    board = scaled_target(tmp_path / "target-15mm-as-14.15.json", 15.0 / 15.9)
    out = tmp_path / "printer.json"
    argv = ["calibrate", "printer", SCAN, "--board", board, "--dpi", "300", "-o", out]
    assert run(argv) == 0
    err = capsys.readouterr().err
    profile = json.loads(out.read_text())
    assert profile["scale_x"] == pytest.approx(1.06, abs=0.006)  # and the reference printer's own +0.4 %
    assert len(profile["warnings"]) == 2 and "beyond what printers do" in profile["warnings"][0]
    assert f"warning: {profile['warnings'][0]}" in err
    out.unlink()
    assert run([*argv, "--strict"]) == 1
    assert "not a printer's scale (--strict)" in one_line(capsys) and not out.exists()
    # the true definition: no warning
    assert run(["calibrate", "printer", SCAN, "--board", TARGET, "--dpi", "300", "-o", out, "--strict", "-q"]) == 0
    assert json.loads(out.read_text())["warnings"] == []


# --- 6. tracebacks on absurd values -------------------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["flatten", "{w}/part.obj", "--dpi", "5e-324"], "--dpi 5e-324: must be between 1 and 10000"),
        (["flatten", "{w}/part.obj", "--dpi", "1e308"], "--dpi 1e308: must be between 1 and 10000"),
        (["flatten", "{w}/part.obj", "--corners", "99999999999999999999,1,2,3"], "--corners 99999999999999999999"),
        (["pdf", "{w}/design", "--paper", ".x."], "--paper '.x.': each side '.': not a number"),
        (["render", "{w}/design", "--orbit", "0,60,250", "--seed", "-1"], "--seed -1: must be between 0 and"),
        (["render", "{w}/design", "--orbit", "0,60,250", "--film-scale-pct", "-100"], "--film-scale-pct -100"),
        (["render", "{w}/design", "--orbit", "0,60,1e308"], "--orbit 0,60,1e308: distance 1e+308"),
        (["render", "{w}/design", "--orbit", "0,60,250", "--size", "1e3x8"], "a side '1e3': not a whole number"),
        (["board", "charuco", "--first-id", "99999999999999999999"], "--first-id 99999999999999999999"),
        (["board", "charuco", "--squares", "2x2"], "--squares 2x2: a ChArUco board needs at least 3 x 3"),
        (["validate", "{w}/design", "{w}/photo.png", "--camera", "{w}/photo.json", "--jobs", "-1"], "--jobs -1"),
        (["calibrate", "check", "{w}/photo.json", "{w}/photo.png", "--tolerance-px", "nan"], "--tolerance-px nan"),
    ],
    ids=lambda v: v[0] if isinstance(v, list) else None,
)
def test_absurd_numbers_are_one_usage_line(work, capsys, argv, fragment):
    before = tree(work)
    assert run([a.replace("{w}", str(work)) for a in [*argv, "-q"]]) == 2
    line = one_line(capsys)
    assert line.startswith(f"workbench {argv[0]}: error: ") and fragment in line, line
    assert tree(work) == before


@pytest.mark.parametrize("dpi", ["5e-324", "1e308", "0.5"])
def test_a_job_dpi_that_is_absurd_is_one_line(work, capsys, dpi):
    (work / "job.toml").write_text((work / "job.toml").read_text().replace("dpi = 30", f"dpi = {dpi}"))
    assert run(["design", work / "job.toml", "--out", work / "out", "-q"]) == 1
    assert "print.dpi: must be" in one_line(capsys) and not (work / "out").exists()


def test_caches_go_to_a_temporary_folder_when_neither_install_nor_home_is_writable(tmp_path):
    from workbench.environment import cache_environment

    blocker = tmp_path / "a-file"
    blocker.write_text("")
    # HOME under a file: nothing can be created there; the install likewise
    env = cache_environment({"HOME": str(blocker / "home")}, blocker / "site-packages" / "workbench")
    assert set(env) == {"NUMBA_CACHE_DIR", "MPLCONFIGDIR"}
    assert all(Path(v).parent.name.startswith("workbench-cache-") for v in env.values())
    # a writable HOME: numba beside the source; matplotlib always in the workbench's own cache
    assert cache_environment({"HOME": str(tmp_path)}, blocker / "workbench") == {
        "MPLCONFIGDIR": str(tmp_path / ".cache" / "workbench" / "matplotlib")
    }
    # an explicit setting: nothing changed
    assert cache_environment({"HOME": str(blocker), "NUMBA_CACHE_DIR": "x", "MPLCONFIGDIR": "y"}, blocker) == {}


# --- 8. errors that name their file or option; the view image's size ----------------------------


def test_a_corner_error_names_the_job_key(work, capsys):
    job = copy.deepcopy(BASE_JOB)
    job["object"]["corners"] = [0, 1, 2, 1000]
    assert run(["design", write_job(work, job), "--out", work / "out", "-q"]) == 1
    line = one_line(capsys)
    assert f"{work / 'job.toml'}: object.corners 0,1,2,1000: corner 1000 does not exist" in line, line


def test_a_flatten_corner_error_names_the_option_and_the_mesh(work, capsys):
    assert run(["flatten", work / "part.obj", "--corners", "0,1,2,1000", "--out", work / "o", "-q"]) == 1
    assert f"{work / 'part.obj'}: --corners 0,1,2,1000: corner 1000 does not exist" in one_line(capsys)


def test_a_board_error_names_the_option(tmp_path, capsys):
    assert run(["board", "charuco", "--first-id", "240", "-o", tmp_path / "b.pdf", "-q"]) == 2
    assert "--first-id 240: 17 markers from id 240 do not fit in DICT_5X5_250" in one_line(capsys)


def test_a_camera_that_sees_nothing_names_the_camera(work, capsys):
    truth = json.loads((work / "photo.json").read_text())
    turn = np.diag([-1.0, 1.0, -1.0])  # about the camera's y axis: the same place, looking away
    truth["R"] = (turn @ np.asarray(truth["R"])).tolist()
    truth["t"] = (turn @ np.asarray(truth["t"])).tolist()
    (work / "away.json").write_text(json.dumps(truth))
    argv = ["render", work / "design", "--camera", work / "away.json", "--no-fixture", "-o", work / "p.png", "-q"]
    assert run(argv) == 1
    assert f"--camera {work / 'away.json'}: the camera sees nothing of the object" in one_line(capsys)


def test_calibrate_camera_names_its_photos(work, capsys, monkeypatch):
    argv = ["calibrate", "camera", work / "photo.png", "--board", TARGET, "-o", work / "cam.json", "-q"]
    assert run(argv) == 1
    line = one_line(capsys)
    assert line.startswith(f"workbench calibrate: error: {TARGET}: 0 usable views") and str(work / "photo.png") in line


def png_header(width: int, height: int) -> bytes:
    """A PNG whose header says ``width`` x ``height`` (8-bit RGB), with no pixel data behind it."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b"")


def test_a_view_image_of_400_megapixels_is_refused_from_its_header(work, capsys):
    (work / "huge.png").write_bytes(png_header(20000, 20000))
    job = copy.deepcopy(BASE_JOB)
    job["views"][0]["image"] = "huge.png"
    assert run(["design", write_job(work, job), "--out", work / "out", "-q"]) == 1
    line = one_line(capsys)
    assert "views[0].image: " in line and "20000 x 20000 px (400 Mpx)" in line and "at most 100 Mpx" in line, line


@pytest.mark.parametrize("where", ["object", "film"])
def test_a_20_digit_corner_in_the_job_is_one_line(work, capsys, where):
    job = copy.deepcopy(BASE_JOB)
    huge = [0, 9, 99999999999999999999, 70]
    if where == "object":
        job["object"]["corners"] = huge
    else:
        (work / "all.txt").write_text(" ".join(map(str, range(126))))
        job["films"] = [{"name": "all", "faces": "all.txt", "corners": huge}]
    assert run(["design", write_job(work, job), "--out", work / "out", "-q"]) == 1
    key = "object.corners" if where == "object" else "films[0].corners"
    assert f"{key}: must be a list of 4 vertex indices" in one_line(capsys) and not (work / "out").exists()


def test_a_tampered_file_list_removes_nothing_outside_the_folder(tmp_path):
    outside = tmp_path / "outside.txt"
    outside.write_text("not the folder's")
    out = tmp_path / "out"
    atomic.write_folder(out, {out / "a.txt": b"a"})
    (out / "link").symlink_to(tmp_path, target_is_directory=True)
    (out / atomic.MANIFEST).write_text(".\n../outside.txt\n/etc/hostname\nlink/outside.txt\n\na.txt\n")
    atomic.write_folder(out, {out / "b.txt": b"b"})
    assert outside.read_text() == "not the folder's"
    assert sorted(p.name for p in out.iterdir()) == [atomic.MANIFEST, "b.txt", "link"]  # a.txt: stale, removed


def test_an_output_named_as_a_folders_file_list_is_refused(work, capsys):
    before = tree(work)
    assert run(["pdf", work / "design", "-o", work / "design" / atomic.MANIFEST, "-q"]) == 1
    assert "list of its files" in one_line(capsys) and tree(work) == before


def test_calibrate_camera_names_its_photos_when_its_reason_does_not(work, capsys, monkeypatch):
    from workbench.commands import calibrate

    def too_few(images, board):
        raise calibrate.WorkbenchError("2 usable views of the board, need at least 5")

    monkeypatch.setattr(calibrate, "calibrate_camera", too_few)
    argv = ["calibrate", "camera", work / "photo.png", "--board", TARGET, "-o", work / "cam.json", "-q"]
    assert run(argv) == 1
    assert f"{work / 'photo.png'} (board {TARGET}): 2 usable views of the board" in one_line(capsys)

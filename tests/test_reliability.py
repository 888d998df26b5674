"""Issue 14: ordinary bad or unusual inputs to every command give no traceback, the documented
exit status (1 for input, 2 for the command line), one line naming the file and key, and write nothing."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT

from workbench.cli import main
from workbench.mesh.io import format_obj

DEFAULT = ROOT / "fixtures" / "default"


def one_line(capsys) -> str:
    """The one line a failed command wrote to stderr (and no traceback, no warning)."""
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "Traceback" not in err[0] and "Warning" not in err[0]
    return err[0]


def tree(path) -> dict:
    """Every file under ``path`` with its bytes, to show that nothing changed."""
    return {p.relative_to(path): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    """A small design of the default job (50 dpi) and one synthetic photo of it with its truth."""
    root = tmp_path_factory.mktemp("rel")
    for name in ("part.obj", "logo.png", "front.png"):
        shutil.copy(DEFAULT / name, root / name)
    (root / "job.toml").write_text((DEFAULT / "job.toml").read_text().replace("dpi = 300", "dpi = 50"))
    d = root / "design"
    assert main(["design", str(root / "job.toml"), "--out", str(d), "-q"]) == 0
    photo = root / "photo.png"
    assert main(["render", str(d), "--orbit", "10,55,330", "--size", "800x600", "-o", str(photo), "-q"]) == 0
    return d, photo


def copy_design(design, tmp_path):
    d = tmp_path / "design"
    shutil.copytree(design[0], d)
    return d


# --- validate: a camera profile no camera has -------------------------------------------------


@pytest.mark.parametrize(
    ("K", "fragment"),
    [
        ([[0, 0, 0], [0, 0, 0], [0, 0, 0]], "K: focal lengths fx 0, fy 0 must be positive"),
        ([[float("nan"), 0, 400], [0, 700, 300], [0, 0, 1]], "K: must be a 3x3 array of finite numbers"),
        ([[-700, 0, 400], [0, 700, 300], [0, 0, 1]], "K: focal lengths fx -700, fy 700 must be positive"),
    ],
    ids=["zeros", "nan", "negative-fx"],
)
def test_validate_with_an_implausible_profile_marks_each_photo_invalid(design, tmp_path, capsys, K, fragment):
    d, photo = design
    profile = json.loads(photo.with_suffix(".json").read_text())
    profile["K"] = K
    bad = tmp_path / "bad-profile.json"
    bad.write_text(json.dumps(profile))
    out = tmp_path / "v"
    # two photos: the batch goes on past the first
    status = main(["validate", str(d), str(photo), str(photo), "--camera", str(bad), "--out", str(out), "-q"])
    assert status == 0
    assert "Traceback" not in capsys.readouterr().err
    report = json.loads((out / "validation.json").read_text())
    assert len(report["photos"]) == 2
    for entry in report["photos"]:
        assert entry["verdict"] == "INVALID"
        assert "bad-profile.json" in entry["reason"] and fragment in entry["reason"], entry["reason"]


def test_photos_of_one_name_from_two_folders_get_distinct_pictures(design, tmp_path):
    d, photo = design
    for folder in ("monday", "tuesday"):
        (tmp_path / folder).mkdir()
        shutil.copy(photo, tmp_path / folder / "photo.png")
    out = tmp_path / "v"
    args = ["validate", str(d), str(tmp_path / "monday" / "photo.png"), str(tmp_path / "tuesday" / "photo.png")]
    assert main([*args, "--camera", str(photo.with_suffix(".json")), "--out", str(out), "-q"]) == 0
    warped = sorted(p.name for p in out.glob("*_warped_*.png"))
    assert len(warped) == 2 and warped[0].startswith("monday_photo") and warped[1].startswith("tuesday_photo")


def test_a_photo_that_is_a_directory_is_invalid_and_says_so(design, tmp_path):
    d, photo = design
    folder = tmp_path / "shots"
    folder.mkdir()
    out = tmp_path / "v"
    assert main(["validate", str(d), str(folder), "--camera", str(photo.with_suffix(".json")), "--out", str(out)]) == 0
    entry = json.loads((out / "validation.json").read_text())["photos"][0]
    assert entry["verdict"] == "INVALID" and "is a directory" in entry["reason"]


# --- design folders with a file at fault ------------------------------------------------------


@pytest.mark.parametrize(
    ("file", "edit", "fragment"),
    [
        ("fixture.json", lambda f: f.pop("origin_mm"), "fixture.json: origin_mm: missing"),
        ("fixture.json", lambda f: f["markers"].pop("ids"), "fixture.json: markers.ids: missing"),
        ("fixture.json", lambda f: f.update(squares=[4, 4]), "fixture.json: charuco_corners.board_mm: 63 entries"),
        ("design.json", lambda f: f["views"][0]["camera"].update(K=[1, 2]), "design.json: views[0].camera.K: must be"),
        ("design.json", lambda f: f["print"].update(dpi="fifty"), "design.json: print.dpi: must be a number"),
    ],
    ids=["fixture-origin", "fixture-ids", "fixture-count", "design-K", "design-dpi"],
)
@pytest.mark.parametrize("command", ["render", "validate"])
def test_a_design_file_at_fault_is_one_line_naming_file_and_key(
    design, tmp_path, capsys, file, edit, fragment, command
):
    d = copy_design(design, tmp_path)
    data = json.loads((d / file).read_text())
    edit(data)
    (d / file).write_text(json.dumps(data))
    before = tree(tmp_path)
    if command == "render":
        argv = ["render", str(d), "--view", "logo", "-o", str(tmp_path / "p.png")]
    else:
        photo = design[1]
        argv = ["validate", str(d), str(photo), "--camera", str(photo.with_suffix(".json"))]
    assert main(argv) == 1
    line = one_line(capsys)
    assert line.startswith(f"workbench {command}: error:") and fragment in line, line
    assert tree(tmp_path) == before


# --- calibrate --------------------------------------------------------------------------------


def test_calibrate_check_given_a_board_definition(tmp_path, capsys):
    board = ROOT / "calib" / "boards" / "printer-target-A5.json"
    scan = ROOT / "calib" / "regression" / "printer-target-scan-300dpi.png"
    assert main(["calibrate", "check", str(board), str(scan)]) == 1
    line = one_line(capsys)
    assert f"{board}: kind: must be one of camera-profile, printer-profile" in line


def test_calibrate_check_names_the_bad_scan(tmp_path, capsys):
    prof = ROOT / "calib" / "printers" / "reference-laser.json"
    scan = ROOT / "calib" / "regression" / "printer-target-scan-300dpi.png"
    blank = tmp_path / "blank.png"
    from workbench.export import png_bytes

    blank.write_bytes(png_bytes(np.full((300, 400, 3), 255, np.uint8), 300))
    assert main(["calibrate", "check", str(prof), str(scan), str(blank), "-q"]) == 1
    line = one_line(capsys)
    assert f"{blank}:" in line and "no markers" in line


def test_calibrate_printer_refuses_an_implausible_scale_and_names_the_dpi(tmp_path, capsys):
    import cv2

    # the regression scan is 300 dpi; stripped of its dpi tag and measured as 600 dpi it says -50 %
    scan = ROOT / "calib" / "regression" / "printer-target-scan-300dpi.png"
    untagged = tmp_path / "scan.png"
    untagged.write_bytes(cv2.imencode(".png", cv2.imread(str(scan)))[1].tobytes())
    board = ROOT / "calib" / "boards" / "printer-target-A5.json"
    out = tmp_path / "printer.json"
    argv = ["calibrate", "printer", str(untagged), "--board", str(board), "--dpi", "600", "-o", str(out), "-q"]
    assert main(argv) == 1
    line = one_line(capsys)
    assert "measured scale x -49.8 % is not a printer's (pdf accepts 0.8 to 1.25)" in line
    assert "the scan records no dpi and --dpi 600 was given; at 300 dpi the scale would be +0.42 %" in line
    assert not out.exists()


# --- render -----------------------------------------------------------------------------------


def test_render_refuses_a_size_beyond_memory_before_any_work(design, tmp_path, capsys, monkeypatch):
    import time

    from workbench.commands import render

    monkeypatch.setattr(render, "physical_memory", lambda: 16 * 2**30)
    out = tmp_path / "big.png"
    t0 = time.perf_counter()
    assert main(["render", str(design[0]), "--orbit", "10,55,330", "--size", "20000x15000", "-o", str(out)]) == 1
    assert time.perf_counter() - t0 < 10
    line = one_line(capsys)
    assert "--size 20000x15000 with --supersample 2 needs about" in line and "lower --size" in line
    assert not out.exists()


@pytest.mark.parametrize(
    ("extra", "fragment"),
    [
        (["--camera", "{truth}", "--size", "640x480"], "--size does not apply to --camera"),
        (["--camera", "{truth}", "--fov-deg", "30"], "--fov-deg does not apply to --camera"),
        (["--view", "logo", "--fov-deg", "30"], "--fov-deg does not apply to --view"),
        (["--view", "logo", "--size", "640x100"], "keep its aspect ratio"),
        (["--orbit", "10,55,330", "--intrinsics", "{truth}", "--size", "640x480"], "--size does not apply with"),
        (["--orbit", "10,55,330", "--fov-deg", "0"], "--fov-deg 0: must be between 0 and 180"),
    ],
    ids=["size-camera", "fov-camera", "fov-view", "size-aspect", "size-intrinsics", "fov-zero"],
)
def test_render_options_that_would_be_ignored_are_usage_errors(design, tmp_path, capsys, extra, fragment):
    d, photo = design
    out = tmp_path / "p.png"
    args = [a.replace("{truth}", str(photo.with_suffix(".json"))) for a in extra]
    assert main(["render", str(d), *args, "-o", str(out)]) == 2
    line = one_line(capsys)
    assert line.startswith("workbench render: error:") and fragment in line, line
    assert not out.exists()


# --- meshes and paths -------------------------------------------------------------------------


def test_a_mesh_path_that_is_a_directory_says_so(tmp_path, capsys):
    folder = tmp_path / "part.obj"
    folder.mkdir()
    assert main(["flatten", str(folder), "--out", str(tmp_path / "o")]) == 1
    assert f"{folder}: is a directory, not a mesh file" in one_line(capsys)


@pytest.mark.parametrize(
    ("content", "said"),
    [(b"", "the file is empty"), (b"solid empty\nendsolid empty\n", "the file holds no triangles")],
    ids=["zero-bytes", "no-facets"],
)
def test_an_empty_stl_is_one_clear_line(tmp_path, capsys, content, said):
    stl = tmp_path / "empty.stl"
    stl.write_bytes(content)
    assert main(["flatten", str(stl), "--out", str(tmp_path / "o")]) == 1
    assert f"{stl}: {said}" in one_line(capsys)
    assert not (tmp_path / "o").exists()


def test_a_job_image_that_is_a_directory_says_so(tmp_path, capsys):
    for name in ("part.obj", "front.png"):
        shutil.copy(DEFAULT / name, tmp_path / name)
    (tmp_path / "logo.png").mkdir()
    (tmp_path / "job.toml").write_text((DEFAULT / "job.toml").read_text())
    assert main(["design", str(tmp_path / "job.toml"), "--out", str(tmp_path / "o")]) == 1
    line = one_line(capsys)
    assert "views[0].image: 'logo.png' is a directory" in line


def test_a_view_name_that_would_leave_the_output_folder_is_refused(tmp_path, capsys):
    for name in ("part.obj", "logo.png", "front.png"):
        shutil.copy(DEFAULT / name, tmp_path / name)
    job = (DEFAULT / "job.toml").read_text().replace('name = "logo"', 'name = "../../escaped"')
    (tmp_path / "job.toml").write_text(job)
    assert main(["design", str(tmp_path / "job.toml"), "--out", str(tmp_path / "o" / "d")]) == 1
    line = one_line(capsys)
    assert "views[0].name: must be 1 to 64 letters, digits" in line and "'../../escaped'" in line
    assert not list(tmp_path.rglob("*escaped*"))


def test_flatten_scale_below_any_film_is_refused(tmp_path, capsys):
    V = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0], [5, 5, 0]], float)
    F = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    mesh = tmp_path / "m.obj"
    mesh.write_bytes(format_obj(V, F))
    assert main(["flatten", str(mesh), "--scale", "width=1e-300", "--out", str(tmp_path / "o")]) == 2
    assert "--scale width=1e-300: width must be a number of mm from 0.01 to 100000" in one_line(capsys)
    assert not (tmp_path / "o").exists()


def test_flatten_of_a_grid_without_its_corner_triangle_prints_no_warning(tmp_path, capsys, grid):
    # the first traceback: a 10 x 8 grid with its corner triangle removed (still a disc)
    P, F = grid(10, 8, np.random.default_rng(0))
    V = np.column_stack([P * [90, 70], np.zeros(len(P))])
    keep = ~(F == 0).any(1)
    used = np.unique(F[keep])
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    mesh = tmp_path / "grid.obj"
    mesh.write_bytes(format_obj(V[used], remap[F[keep]]))
    status = main(["flatten", str(mesh), "--out", str(tmp_path / "o"), "-q"])
    err = capsys.readouterr().err
    assert "Traceback" not in err and "Warning" not in err and "warning" not in err.lower()
    assert status in (0, 1) and len(err.strip().splitlines()) == (0 if status == 0 else 1)


# --- one exit-status convention ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "status", "fragment"),
    [
        (["validate", "{d}", "{photo}", "--camera", "{truth}", "--tolerance-mm", "-1"], 2, "--tolerance-mm -1"),
        (["pdf", "{d}", "--bleed-mm", "80"], 2, "--bleed-mm 80: must be between 0 and 50 mm"),
        (["calibrate", "check", "{calib}", "{scan}", "--tolerance-pct", "0"], 2, "--tolerance-pct 0"),
        (["calibrate", "printer", "{scan}", "--board", "{board}", "--dpi", "0", "-o", "{tmp}/p.json"], 2, "--dpi 0"),
        (["render", "{d}", "--orbit", "10,55,330", "--supersample", "0"], 2, "--supersample"),
        (["flatten", "{tmp}/none.obj", "--dpi", "0"], 2, "--dpi 0"),
        (["board", "charuco", "--squares", "2x2", "-o", "{tmp}/b.pdf"], 2, "at least 3 x 3 squares"),
        (["board", "charuco", "--dictionary", "NOPE", "-o", "{tmp}/b.pdf"], 2, "unknown ArUco dictionary"),
        (["design", "{tmp}/none.toml"], 1, "no such job file"),
        (["pdf", "{tmp}"], 1, "design.json: missing"),
        (["render", "{d}", "--camera", "{tmp}/none.json", "-o", "{tmp}/p.png"], 1, "no such camera file"),
        (["validate", "{d}", "{photo}", "--camera", "{tmp}/none.json"], 1, "no such camera profile"),
        (["calibrate", "camera", "{photo}", "--board", "{tmp}/none.json", "-o", "{tmp}/c.json"], 1, "no such board"),
        (["flatten"], 2, "the following arguments are required"),
        (["render", "{d}", "--orbit", "1,2"], 2, "--orbit '1,2': give 3 comma-separated numbers"),
    ],
)
def test_one_exit_status_convention(design, tmp_path, capsys, argv, status, fragment):
    d, photo = design
    subs = {
        "{d}": str(d),
        "{photo}": str(photo),
        "{truth}": str(photo.with_suffix(".json")),
        "{tmp}": str(tmp_path),
        "{calib}": str(ROOT / "calib" / "printers" / "reference-laser.json"),
        "{scan}": str(ROOT / "calib" / "regression" / "printer-target-scan-300dpi.png"),
        "{board}": str(ROOT / "calib" / "boards" / "printer-target-A5.json"),
    }
    args = []
    for a in argv:
        for k, v in subs.items():
            a = a.replace(k, v)
        args.append(a)
    before = tree(d)
    assert main(args) == status
    line = one_line(capsys)
    assert line.startswith(f"workbench {argv[0]}: error:") and fragment in line, line
    assert tree(d) == before and sorted(tmp_path.iterdir()) == []


# --- calibrate camera: views that cannot determine the intrinsics ----------------------------


def straight_down_photos(tmp_path, board, n=6, size=(1600, 1200)):
    """Views of the board from straight above, moved sideways: its normal never turns."""
    from test_calibrate import K_TRUE

    from workbench.camera import Camera
    from workbench.export import png_bytes
    from workbench.render.imperfections import Imperfections
    from workbench.render.photo import board_scene, render_photo

    scene = board_scene(board)
    paths = []
    for k in range(n):
        dx, dy = 12.0 * (k % 3 - 1), 10.0 * (k // 3 - 0.5)
        centre = np.array([112.5 + dx, -87.5 + dy, 0.0])
        pose = Camera.look_at(centre + [0, 0, 330], centre, [0, 1, 0], 50, *size)
        cam = Camera(K_TRUE, pose.R, pose.t, *size)
        p = tmp_path / f"down{k}.png"
        p.write_bytes(png_bytes(render_photo(scene, cam, Imperfections(noise=1.0, seed=k))))
        paths.append(p)
    return paths


def test_calibrate_camera_refuses_the_same_photo_six_times(tmp_path, capsys):
    from test_calibrate import board_definition, calibration_photos

    board, board_path = board_definition(tmp_path)
    photo = calibration_photos(tmp_path, board, n=1)[0]
    copies = []
    for k in range(6):
        copies.append(tmp_path / f"copy{k}.png")
        shutil.copy(photo, copies[-1])
    out = tmp_path / "cam.json"
    argv = ["calibrate", "camera", *map(str, copies), "--board", str(board_path), "-o", str(out), "-q"]
    assert main(argv) == 1
    line = one_line(capsys)
    assert "1 usable views of the board, need at least 5" in line
    assert f"{copies[1]}: near-duplicate of {copies[0]} (the same pose" in line
    assert not out.exists()


def test_calibrate_camera_refuses_views_without_tilt_variety(tmp_path, capsys):
    from test_calibrate import board_definition

    board, board_path = board_definition(tmp_path)
    photos = straight_down_photos(tmp_path, board)
    out = tmp_path / "cam.json"
    argv = ["calibrate", "camera", *map(str, photos), "--board", str(board_path), "-o", str(out), "-q"]
    assert main(argv) == 1
    line = one_line(capsys)
    assert "the board faces the camera the same way in every view" in line and "tilt the board" in line
    assert not out.exists()


def test_calibrate_camera_drops_a_view_whose_corners_lie_on_one_row(tmp_path, capsys, monkeypatch):
    from test_calibrate import board_definition, calibration_photos

    from workbench import calibration

    board, board_path = board_definition(tmp_path)
    photos = calibration_photos(tmp_path, board, n=6)
    detect, calls = calibration.detect_corners, []

    def one_row_in_the_last(gray, definition):
        # what the detector gives when only one row of the board is in the picture
        px, ids, problem = detect(gray, definition)
        calls.append(1)
        if len(calls) == len(photos):
            row = ids // 8 == np.bincount(ids // 8).argmax()
            px, ids = px[row], ids[row]
        return px, ids, problem

    monkeypatch.setattr(calibration, "detect_corners", one_row_in_the_last)
    out = tmp_path / "cam.json"
    argv = ["calibrate", "camera", *map(str, photos), "--board", str(board_path), "-o", str(out), "-q"]
    assert main(argv) == 0
    views = {v["name"]: v for v in json.loads(out.read_text())["views"]}  # relative to the profile's folder
    last = views[photos[-1].name]
    assert not last["used"] and "lie on one line of the board" in last["reason"], last
    assert all(views[p.name]["used"] for p in photos[:-1])


# --- outputs that travel ----------------------------------------------------------------------


def test_a_design_folder_moved_elsewhere_still_renders_validates_and_prints(design, tmp_path):
    d, photo = design
    moved = tmp_path / "elsewhere" / "deeper" / "design"
    shutil.copytree(d, moved)
    info = json.loads((moved / "design.json").read_text())
    # paths relative to the design folder, each with its hash
    assert info["job"]["file"] == "../job.toml" and len(info["job"]["sha256"]) == 64
    assert {i["file"] for i in info["inputs"]} == {"../part.obj", "../logo.png", "../front.png"}
    assert not any(i["file"].startswith("/") for i in info["inputs"])
    shot = tmp_path / "shot.png"
    assert main(["render", str(moved), "--orbit", "10,55,330", "--size", "800x600", "-o", str(shot), "-q"]) == 0
    truth = json.loads(shot.with_suffix(".json").read_text())
    assert truth["design"]["dir"] == "elsewhere/deeper/design"
    out = tmp_path / "report"
    assert main(["validate", str(moved), str(shot), "--camera", str(shot.with_suffix(".json")), "--out", str(out)]) == 0
    report = json.loads((out / "validation.json").read_text())
    assert report["photos"][0]["verdict"] == "PASS", report["photos"][0]["reason"]
    assert report["photos"][0]["photo"] == "../shot.png" and report["design"]["dir"] == "../elsewhere/deeper/design"
    assert report["camera_profile"]["file"] == "../shot.json"
    assert main(["pdf", str(moved), "-o", str(tmp_path / "print.pdf"), "-q"]) == 0


def test_calibrate_check_reads_a_board_path_relative_to_the_profile_and_an_absolute_one(tmp_path):
    scan = ROOT / "calib" / "regression" / "printer-target-scan-300dpi.png"
    prof = json.loads((ROOT / "calib" / "printers" / "reference-laser.json").read_text())
    # an older profile recorded the absolute path of its board
    prof["board"]["file"] = str(ROOT / "calib" / "boards" / "printer-target-A5.json")
    old = tmp_path / "old.json"
    old.write_text(json.dumps(prof))
    assert main(["calibrate", "check", str(old), str(scan), "-q"]) == 0
    # a profile moved with its board beside it
    shutil.copy(ROOT / "calib" / "boards" / "printer-target-A5.json", tmp_path / "board.json")
    prof["board"]["file"] = "board.json"
    moved = tmp_path / "moved.json"
    moved.write_text(json.dumps(prof))
    assert main(["calibrate", "check", str(moved), str(scan), "-q"]) == 0


# --- all-or-nothing output folders ------------------------------------------------------------


def test_a_failure_while_writing_a_folder_leaves_the_earlier_one_intact(design, tmp_path, monkeypatch, capsys):
    from workbench import atomic

    d = copy_design(design, tmp_path)
    (d / "validation").mkdir()
    (d / "validation" / "notes.txt").write_text("kept")  # another command's output inside the folder
    before = tree(tmp_path)
    write, calls = atomic._write_file, []

    def fail_at_the_fifth(path, data):
        calls.append(path)
        if len(calls) == 5:
            raise OSError(28, "No space left on device")
        write(path, data)

    monkeypatch.setattr(atomic, "_write_file", fail_at_the_fifth)
    job = design[0].parent / "job.toml"
    assert main(["design", str(job), "--out", str(d), "-q"]) == 1
    line = one_line(capsys)
    assert "cannot write: No space left on device" in line
    assert tree(tmp_path) == before  # the earlier design, its validation notes, no temporary left


def test_a_failure_at_the_renames_puts_the_earlier_folder_back(tmp_path, monkeypatch):
    from workbench import atomic
    from workbench.errors import WorkbenchError

    out = tmp_path / "out"
    atomic.write_folder(out, {out / "a.txt": b"old a", out / "b.txt": b"old b", out / "c.txt": b"old c"})
    (out / "other.txt").write_text("not ours")
    before = tree(tmp_path)
    replace = atomic.os.replace

    def fail_on_b(src, dst):
        if Path(dst).name == "b.txt" and ".workbench.tmp-" in str(src):
            raise OSError(13, "Permission denied")
        replace(src, dst)

    monkeypatch.setattr(atomic.os, "replace", fail_on_b)
    # a.txt replaced, then b.txt fails: a.txt is put back, c.txt (stale) not removed
    with pytest.raises(WorkbenchError, match="cannot write: Permission denied"):
        atomic.write_folder(out, {out / "a.txt": b"new a", out / "b.txt": b"new b"})
    assert tree(tmp_path) == before
    monkeypatch.undo()
    atomic.write_folder(out, {out / "a.txt": b"new a", out / "b.txt": b"new b"})
    manifest = (out / atomic.MANIFEST).read_bytes()
    assert tree(out) == {
        Path("a.txt"): b"new a",
        Path("b.txt"): b"new b",
        Path("other.txt"): b"not ours",
        Path(atomic.MANIFEST): manifest,
    }
    assert manifest.decode().splitlines()[1:] == ["a.txt", "b.txt"]


def test_a_pair_of_files_is_put_back_when_the_second_rename_fails(tmp_path, monkeypatch):
    from workbench import atomic
    from workbench.errors import WorkbenchError

    a, b = tmp_path / "photo.png", tmp_path / "photo.json"
    atomic.write_files({a: b"old png", b: b"old json"})
    replace = atomic.os.replace

    def fail_on_json(src, dst):
        if Path(dst) == b:
            raise OSError(5, "Input/output error")
        replace(src, dst)

    monkeypatch.setattr(atomic.os, "replace", fail_on_json)
    with pytest.raises(WorkbenchError, match="photo.json: cannot write"):
        atomic.write_files({a: b"new png", b: b"new json"})
    assert tree(tmp_path) == {Path("photo.png"): b"old png", Path("photo.json"): b"old json"}


def test_a_photo_with_half_the_part_painted_over_fails(design, tmp_path):
    import cv2

    from workbench.camera import Camera
    from workbench.design_dir import Design

    d = design[0]
    ok = tmp_path / "ok.png"
    argv = ["render", str(d), "--orbit", "10,55,330", "--size", "2000x1500", "--realistic", "-o", str(ok), "-q"]
    assert main(argv) == 0
    truth = json.loads(ok.with_suffix(".json").read_text())
    cam = Camera(np.array(truth["K"]), np.array(truth["R"]), np.array(truth["t"]), 2000, 1500)
    xy, _ = cam.project(Design(d).V)
    (x0, y0), (x1, y1) = xy.min(axis=0).astype(int), xy.max(axis=0).astype(int)
    img = cv2.imread(str(ok))
    img[y0:y1, (x0 + x1) // 2 : x1] = 128  # the right half of the part painted grey
    half = tmp_path / "half.png"
    cv2.imwrite(str(half), img)
    out = tmp_path / "v"
    argv = ["validate", str(d), str(ok), str(half), "--camera", str(ok.with_suffix(".json")), "--out", str(out)]
    assert main(argv) == 0
    good, bad = json.loads((out / "validation.json").read_text())["photos"]
    assert good["verdict"] == "PASS" and good["tiles"] == good["tiles_examined"]
    # what is painted over is the dense colour test's to find: a defect covering most of that half
    assert bad["verdict"] == "FAIL" and "defect" in bad["reason"], bad["reason"]
    painted = max(d["area_mm2"] for d in bad["defects"])
    assert painted > 1000.0 and bad["defects"][0]["kind"] in ("colour", "missing"), bad["defects"][:2]


def test_library_warnings_never_reach_stderr(tmp_path):
    # in a process of its own: pytest records warnings itself, so only a real stderr shows them
    import subprocess
    import sys

    script = f"""
import sys, warnings
import numpy as np
from workbench.commands import board
from workbench.cli import main
pdf = board.board_pdf
def noisy(*args, **kwargs):
    np.float64(1e308) * np.float64(10.0)  # numpy: overflow encountered in scalar multiply
    warnings.warn("something will change", UserWarning, stacklevel=1)
    return pdf(*args, **kwargs)
board.board_pdf = noisy
warnings.warn("before the command: shown", UserWarning, stacklevel=1)
sys.exit(main(["board", "charuco", "-o", {str(tmp_path / "b.pdf")!r}, "-q"]))
"""
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    # the warning outside the command shows (the check can fail); none from inside it
    assert "before the command: shown" in res.stderr
    assert "something will change" not in res.stderr and "overflow" not in res.stderr, res.stderr


# --- the schema mechanism itself --------------------------------------------------------------


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"views": [{"K": np.eye(3).tolist()}, {"K": [1, 2]}]}, "f.json: views[1].K: must be a 3x3 array"),
        ({"views": [{}]}, "f.json: views[0].K: missing (a 3x3 array of finite numbers)"),
        ({"views": []}, "f.json: views: must be a list of at least 1 items"),
        ({"views": [{"K": np.eye(3).tolist()}], "ids": [1, 2.5]}, "f.json: ids: must be a list of whole numbers"),
        ({"views": [{"K": np.eye(3).tolist()}], "size": {"dpi": 10**400}}, "f.json: size.dpi: must be a number from"),
        ({"views": [{"K": np.eye(3).tolist()}], "size": {"dpi": True}}, "f.json: size.dpi: must be a number from"),
        ({"views": [{"K": np.eye(3).tolist()}], "name": 3}, "f.json: name: must be one of a, b"),
    ],
)
def test_the_schema_names_file_and_key(data, message):
    from workbench.errors import WorkbenchError
    from workbench.jsonfile import Field, check

    fields = {
        "views": Field("list", min_len=1, items=Field("object", fields={"K": Field("array", shape=(3, 3))})),
        "ids": Field("array", required=False, shape=(None,), integer=True),
        "size": Field("object", required=False, default={"dpi": 300}, fields={"dpi": Field("number", lo=1, hi=1e4)}),
        "name": Field("string", required=False, default="a", choices=("a", "b")),
    }
    with pytest.raises(WorkbenchError) as exc:
        check(data, fields, "f.json")
    assert str(exc.value).startswith(message), str(exc.value)


def test_the_schema_fills_in_defaults_and_leaves_unknown_keys():
    from workbench.jsonfile import Field, check

    fields = {"dpi": Field("number", required=False, default=300), "name": Field("string")}
    data = check({"name": "x", "newer_key": [1]}, fields, "f.json")
    assert data == {"name": "x", "dpi": 300, "newer_key": [1]}

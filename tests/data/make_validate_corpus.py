"""Regenerate ``tests/data/validate_corpus/``: real meshes as decorated parts, with artwork as designers make it.

    python tests/data/make_validate_corpus.py [--meshes DIR] [--out DIR]

Each part is one folder with a ``job.toml`` (see ``workbench/job.py``), its mesh (binary PLY,
float32, decimated to at most 6,000 faces) and the images of its views. The meshes are real:
the four test meshes of the project (libigl's tutorial data: ``face``, ``camelhead``,
``lilium``, ``camel_b``; ``--meshes`` is the folder that holds them, read only when it
exists, else the committed copies are kept) and patches of the flatten corpus
(``tests/data/corpus/*.npz``, see ``tests/data/README.md``). Each is oriented with its
area-weighted normal up (+z, the decorated side, faces counter-clockwise seen from it), its
lowest point on z = 0, centred over the origin, and scaled to a part size between 80 and
200 mm (the longest side of its bounding box).

Artwork (:func:`artwork`), one kind per view, 800 x 600 px:

- ``photo``: photographs: matplotlib's sample photo of Grace Hopper (``grace_hopper.jpg``,
  a U.S. Navy portrait, public domain) and a hill-shaded terrain model (``jacksboro_fault_dem.npz``,
  USGS data, public domain), both shipped in matplotlib's ``mpl-data/sample_data``;
- ``gradient``: soft colour fields (low-pass noise, no edge at all);
- ``logo``: a low-contrast logo (about 20 grey levels) on a flat colour;
- ``text``: lines of small text, strokes about 2 px wide, on a light soft field;
- ``checker``: a checker at about 55 % contrast over a soft colour field, with rings.

Everything is deterministic (fixed seeds; libigl's decimation is deterministic), so the
folder regenerates byte for byte from the same inputs.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE / "validate_corpus"
SHARED = HERE.parents[2] / "shared" / "meshes"  # the project's planning meshes, when present
W, H = 800, 600  # view images, 4:3
MAX_FACES = 6000
DPI = 200
KINDS = ("photo", "gradient", "logo", "text", "checker")

# name, source, size mm, outline ("auto": films = "auto", free outlines within max_stretch 1.5),
# views (az, el) in degrees in priority order; az 0 looks from -y, el 90 from above. With two
# views the first (from above) frames the middle of the part only and the second owns the rest,
# as the default job's logo and front views do
PARTS = (
    ("face", "shared:face.obj", 180.0, "free", ((0, 90), (-35, 50))),  # a half head: its own +z is the face
    ("camelhead", "shared:camelhead.off", 120.0, "auto", ((0, 90),)),
    ("lilium", "shared:lilium.obj", 100.0, "free", ((0, 90), (25, 55))),
    ("camel_b", "shared:camel_b.obj", 150.0, "auto", ((0, 90),)),
    ("bunny", "corpus:bunny-0", 100.0, "free", ((0, 90), (30, 55))),
    ("cow", "corpus:cow-0", 120.0, "free", ((0, 90),)),
    ("lion", "corpus:lion-0", 90.0, "free", ((0, 90), (-30, 55))),
    ("beetle", "corpus:beetle-0", 140.0, "free", ((0, 90),)),
    ("elephant", "corpus:elephant-0", 160.0, "free", ((0, 90), (20, 50))),
    ("fertility", "corpus:fertility-0", 110.0, "free", ((0, 90),)),
    ("fandisk", "corpus:fandisk-0", 200.0, "free", ((0, 90), (-25, 55))),
    ("arm", "corpus:arm-0", 130.0, "free", ((0, 90),)),
    ("snail", "corpus:snail-0", 80.0, "free", ((0, 90), (35, 50))),
    ("cheburashka", "corpus:cheburashka-0", 100.0, "rectangle", ((0, 90),)),
)
# the decorated side's direction in the source's frame where the area-weighted normal is not it
UP = {"face": (0.0, 0.0, 1.0)}
SOURCES = {
    "shared": "libigl tutorial data (github.com/libigl/libigl-tutorial-data), the project's planning meshes",
    "corpus": "tests/data/corpus (geodesic disc of a libigl tutorial data mesh; see tests/data/README.md)",
}


# ---------------------------------------------------------------------------------------------- meshes


def read_source(source: str, meshes: Path) -> tuple[np.ndarray, np.ndarray]:
    """The source mesh's vertices (float64) and faces (int64)."""
    where, _, name = source.partition(":")
    if where == "corpus":
        d = np.load(HERE / "corpus" / f"{name}.npz")
        return d["V"].astype(np.float64), d["F"].astype(np.int64)
    from workbench.mesh.io import read_mesh

    V, F = read_mesh(meshes / name)
    return np.asarray(V, np.float64), np.asarray(F, np.int64)


def decimate(V: np.ndarray, F: np.ndarray, max_faces: int = MAX_FACES) -> tuple[np.ndarray, np.ndarray]:
    """At most ``max_faces`` faces by libigl's edge collapse (keeps a disc a disc)."""
    if len(F) <= max_faces:
        return V, F
    import igl

    U, G, _, _ = igl.decimate(V, F, max_faces)
    return np.asarray(U, np.float64), np.asarray(G, np.int64)


def place(V: np.ndarray, F: np.ndarray, size_mm: float, up: tuple | None = None) -> np.ndarray:
    """The part as it stands on its fixture: decorated side (area-weighted normal) up, base at z = 0.

    Returns (n, 3) float64 vertices in mm, the bounding box centred over the origin in x and y,
    the longest side of the bounding box ``size_mm``. ``up``: the decorated side's direction in
    the source's frame, where the area-weighted normal is not it (a half head's points sideways).
    """
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]).sum(axis=0) if up is None else np.array(up)
    n /= np.linalg.norm(n)
    # the rotation taking n to +z (Rodrigues about n x z)
    axis = np.cross(n, [0.0, 0.0, 1.0])
    s, c = np.linalg.norm(axis), n[2]
    if s < 1e-12:
        R = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    else:
        k = axis / s
        Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        R = np.eye(3) + s * Kx + (1 - c) * Kx @ Kx
    P = V @ R.T
    # the longer footprint side along x, as the fixture and a print are laid out
    ext = np.ptp(P[:, :2], axis=0)
    if ext[1] > ext[0]:
        P = P @ np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).T
    lo, hi = P.min(axis=0), P.max(axis=0)
    P = (P - [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]) * (size_mm / np.ptp(P, axis=0).max())
    return P


def write_ply(path: Path, V: np.ndarray, F: np.ndarray) -> None:
    """Binary little-endian PLY, float32 vertices and int32 faces, in the given order."""
    head = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(V)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    faces = np.zeros(len(F), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"], faces["i"] = 3, F
    path.write_bytes(head + V.astype("<f4").tobytes() + faces.tobytes())


# ---------------------------------------------------------------------------------------------- artwork


def soft_field(rng: np.random.Generator, sigma: float = 90.0, lo: float = 50.0, hi: float = 210.0) -> np.ndarray:
    """A smooth colour field (H, W, 3) float64: low-pass noise per channel stretched to [lo, hi]."""
    f = cv2.GaussianBlur(rng.standard_normal((H, W, 3)), (0, 0), sigma)
    f -= f.min(axis=(0, 1))
    f /= f.max(axis=(0, 1))
    return lo + (hi - lo) * f


def sample_photo(k: int) -> np.ndarray:
    """One of matplotlib's sample photographs, cropped and resized to W x H (RGB float64)."""
    import matplotlib
    from matplotlib import cbook

    if k % 2 == 0:
        img = cv2.imread(str(Path(matplotlib.get_data_path()) / "sample_data" / "grace_hopper.jpg"))
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    else:
        dem = cbook.get_sample_data("jacksboro_fault_dem.npz")["elevation"].astype(np.float64)
        gy, gx = np.gradient(dem)
        shade = np.clip(0.5 + 0.35 * (-gx - gy) / (np.hypot(gx, gy).mean() * 3 + 1e-9), 0, 1)
        t = (dem - dem.min()) / np.ptp(dem)
        # a terrain colour ramp under the hill shade
        ramp = np.stack([60 + 150 * t, 110 + 90 * t, 70 + 60 * (1 - t)], -1)
        img = np.clip(ramp * (0.45 + 0.9 * shade[..., None]), 0, 255).astype(np.uint8)
    h, w = img.shape[:2]
    # centre crop to 4:3, then area resampling
    if w / h > W / H:
        c = int(round(h * W / H))
        img = img[:, (w - c) // 2 : (w - c) // 2 + c]
    else:
        c = int(round(w * H / W))
        img = img[(h - c) // 2 : (h - c) // 2 + c]
    interp = cv2.INTER_AREA if img.shape[1] > W else cv2.INTER_CUBIC
    return cv2.resize(img, (W, H), interpolation=interp).astype(np.float64)


def artwork(kind: str, seed: int) -> np.ndarray:
    """One view image of the given kind, (H, W, 3) uint8 RGB, deterministic in ``seed``."""
    rng = np.random.default_rng(seed)
    if kind == "photo":
        img = sample_photo(seed // 1000)  # one part the portrait, the next the terrain
    elif kind == "gradient":
        img = soft_field(rng, sigma=110.0, lo=40.0, hi=220.0)
    elif kind == "logo":
        base = rng.uniform(70, 190, 3)
        img = np.broadcast_to(base, (H, W, 3)).copy()
        mark = np.zeros((H, W), np.uint8)
        cx, cy = int(W * rng.uniform(0.35, 0.65)), int(H * rng.uniform(0.35, 0.65))
        cv2.circle(mark, (cx, cy), 150, 255, 18, cv2.LINE_AA)
        cv2.circle(mark, (cx, cy), 70, 255, -1, cv2.LINE_AA)
        cv2.putText(mark, "ACME", (cx - 190, cy + 250), cv2.FONT_HERSHEY_DUPLEX, 3.0, 255, 8, cv2.LINE_AA)
        tone = rng.choice([-1.0, 1.0]) * 20.0  # a low-contrast mark: about 20 grey levels
        img += tone * (mark[..., None] / 255.0) * np.array([1.0, 0.9, 1.1])
    elif kind == "text":
        img = soft_field(rng, sigma=140.0, lo=185.0, hi=240.0)
        ink = np.zeros((H, W), np.uint8)
        words = "ISO 9001 LOT 42 batch PET-G 0.3 mm made in EU recycle 07 serial QA pass no.".split()
        for row, y in enumerate(range(28, H, 26)):
            line = " ".join(rng.choice(words, 9))
            cv2.putText(ink, line, (8 + 11 * (row % 3), y), cv2.FONT_HERSHEY_SIMPLEX, 0.62, 255, 2, cv2.LINE_AA)
        img = img * (1 - 0.75 * ink[..., None] / 255.0)
    elif kind == "checker":
        img = soft_field(rng, sigma=120.0, lo=70.0, hi=200.0)
        n = int(rng.integers(28, 44))
        yy, xx = np.mgrid[0:H, 0:W]
        sq = ((xx // n + yy // n) % 2).astype(np.float64)
        # about 55 % contrast: (max - min) / (max + min) of the two squares' brightness
        img = img * (0.58 + 0.84 * sq)[..., None]
        rings = np.zeros((H, W), np.uint8)
        for r in range(40, 300, 45):
            cv2.circle(rings, (W // 2, H // 2), r, 255, 3, cv2.LINE_AA)
        img = img * (1 - 0.5 * rings[..., None] / 255.0)
    else:
        raise ValueError(f"unknown artwork kind {kind!r}")
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def encode_image(rgb: np.ndarray) -> tuple[str, bytes]:
    """The smaller of PNG and JPEG (quality 92) for this image: flat artwork as PNG, photos as JPEG."""
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    png = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 9])[1].tobytes()
    jpg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 92])[1].tobytes()
    return (".png", png) if len(png) <= 1.5 * len(jpg) else (".jpg", jpg)


# ---------------------------------------------------------------------------------------------- views


def view_camera(V: np.ndarray, az: float, el: float, share: float = 1.0) -> dict:
    """position / look_at / up / fov_deg of a view at azimuth ``az`` and elevation ``el`` that frames the part.

    The camera looks at the centre of the part's bounding box from 2.5 bounding radii away,
    with the field of view that fits the bounding sphere (plus 8 %) into the image's height;
    ``share`` < 1 frames only that share of the sphere's radius (the middle of the part).
    """
    centre = 0.5 * (V.min(axis=0) + V.max(axis=0))
    r = 0.5 * float(np.linalg.norm(np.ptp(V, axis=0)))
    d = 2.5 * r
    a, e = math.radians(az), math.radians(el)
    eye = centre + d * np.array([math.sin(a) * math.cos(e), -math.cos(a) * math.cos(e), math.sin(e)])
    up = [0.0, 1.0, 0.0] if el >= 89 else [0.0, 0.0, 1.0]
    half_v = math.atan(1.08 * share * r / math.sqrt(d * d - r * r))
    fov = 2 * math.degrees(math.atan(math.tan(half_v) * W / H))
    rnd = lambda x: [round(float(v), 3) for v in x]  # noqa: E731
    return {"position": rnd(eye), "look_at": rnd(centre), "up": up, "fov_deg": round(fov, 3)}


def job_toml(name: str, mesh: str, outline: str, views: list[tuple[str, str, dict]], meta: dict) -> str:
    lines = [
        f"# validate corpus: {meta['source']} as a {meta['size_mm']:g} mm part; artwork: "
        + ", ".join(f"{v} = {k}" for v, k, _ in views),
        "# generated by tests/data/make_validate_corpus.py",
        "[object]",
        f'mesh = "{mesh}"',
        'units = "mm"',
        "",
        "[print]",
        f"dpi = {DPI}",
        f'outline = "{"free" if outline == "auto" else outline}"',
        "",
    ]
    if outline == "auto":
        lines[1:1] = ['films = "auto"']
        lines.insert(lines.index('units = "mm"') + 1, 'material = { name = "PET-G film 0.3 mm", max_stretch = 1.5 }')
    for vname, _kind, cam in views:
        lines += [
            "[[views]]",
            f'name = "{vname}"',
            f'image = "{meta["images"][vname]}"',
            f"position = {cam['position']}",
            f"look_at = {cam['look_at']}",
            f"up = {cam['up']}",
            f"fov_deg = {cam['fov_deg']}",
            "",
        ]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--meshes", type=Path, default=SHARED, help="folder with face.obj, camelhead.off, ...")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    index = []
    # the committed index: the source face counts of meshes whose source is not at hand
    old = args.out / "corpus.json"
    known = {p["name"]: p for p in json.loads(old.read_text())["parts"]} if old.is_file() else {}
    for i, (name, source, size, outline, views) in enumerate(PARTS):
        folder = args.out / name
        folder.mkdir(exist_ok=True)
        where, _, file = source.partition(":")
        if where == "shared" and not (args.meshes / file).is_file():
            if not (folder / "part.ply").is_file():
                raise SystemExit(f"{args.meshes / file}: missing, and no committed copy in {folder}")
            from workbench.mesh.io import read_mesh

            V, F = (np.asarray(a, np.float64) for a in read_mesh(folder / "part.ply"))
            source_faces = known.get(name, {}).get("source_faces")
        else:
            V0, F0 = read_source(source, args.meshes)
            source_faces = len(F0)
            V, F = decimate(V0, F0)
            V = place(V, F, size, UP.get(name))
            write_ply(folder / "part.ply", V, F)
        vspecs, images = [], {}
        for k, (az, el) in enumerate(views):
            vname = "top" if el >= 89 else f"side{k}"
            kind = KINDS[(i + 2 * k) % len(KINDS)]
            ext, data = encode_image(artwork(kind, seed=1000 * i + k))
            for old in folder.glob(f"{vname}.*"):
                if old.suffix in (".png", ".jpg"):
                    old.unlink()
            (folder / f"{vname}{ext}").write_bytes(data)
            images[vname] = f"{vname}{ext}"
            share = 0.45 if k == 0 and len(views) > 1 else 1.0
            vspecs.append((vname, kind, view_camera(V, az, el, share), az, el))
        meta = {"source": source, "size_mm": size, "images": images}
        text = job_toml(name, "part.ply", outline, [(v, k, c) for v, k, c, _, _ in vspecs], meta)
        (folder / "job.toml").write_text(text)
        index.append(
            {
                "name": name,
                "source": source,
                "source_licence": SOURCES[where],
                "source_faces": source_faces,
                "faces": len(F),
                "vertices": len(V),
                "size_mm": size,
                "outline": outline,
                "views": [{"name": v, "artwork": k, "az_deg": az, "el_deg": el} for v, k, _, az, el in vspecs],
            }
        )
        print(f"{name}: {len(F)} faces, {size:g} mm, views " + ", ".join(f"{v} ({k})" for v, k, *_ in vspecs))
    (args.out / "corpus.json").write_text(json.dumps({"dpi": DPI, "parts": index}, indent=1) + "\n")


if __name__ == "__main__":
    main()

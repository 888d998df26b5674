"""Synthetic photos: z-buffer rasterisation, perspective-correct texturing, lens and sensor effects."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numba
import numpy as np

from workbench.camera import Camera
from workbench.errors import WorkbenchError
from workbench.mesh.normals import vertex_normals
from workbench.raster import _JIT, depth_buffer
from workbench.render.defects import Defect, apply_defects
from workbench.render.imperfections import Imperfections, film_transform

TABLE_GREY = 90  # what the camera sees around the plate
BOARD_PX_PER_MM = 20.0
PLATE_MARGIN_MM = 10.0  # white paper around the printed board


@dataclass
class Scene:
    """Triangles with textures: the decorated part and, optionally, its fixture plate.

    Attributes
    ----------
    V : (n, 3) float
        Vertices, mm (the part's first, then the plate's four corners).
    F : (m, 3) int
        Triangles (the part's first).
    uv : (n, 2) float
        Texture pixel coordinates of each vertex in its face's texture.
    normals : (n, 3) float
        Unit vertex normals, towards the decorated side.
    face_texture : (m,) int8
        0: the print, 1: the plate.
    textures : list of (h, w, 3) uint8
        The print and the plate's board image.
    n_part_faces : int
        Faces of the part (the plate's come after).
    """

    V: np.ndarray
    F: np.ndarray
    uv: np.ndarray
    normals: np.ndarray
    face_texture: np.ndarray
    textures: list
    n_part_faces: int


def board_texture(definition: dict, ppm: float = BOARD_PX_PER_MM) -> tuple[np.ndarray, float]:
    """The fixture's board as an image with a white margin, and its pixels per mm.

    At 20 px/mm (the default) the squares, and the markers' offsets in them, are whole pixels for
    sizes in 0.05 mm steps, so OpenCV draws every ChArUco and marker corner exactly.
    """
    from workbench.printing.boards import CharucoSpec

    spec = CharucoSpec.from_definition(definition)
    bw, bh = spec.size_mm
    img = spec.opencv().generateImage((int(round(bw * ppm)), int(round(bh * ppm))), marginSize=0, borderBits=1)
    m = int(round(PLATE_MARGIN_MM * ppm))
    extra = int(round(plate_extension_mm(definition) * ppm))
    img = cv2.copyMakeBorder(img, m, m + extra, m, m, cv2.BORDER_CONSTANT, value=255)
    img = cv2.cvtColor(img, cv2.COLOR_GRAY2RGB)
    chart = definition.get("colour_chart")
    if chart is not None:
        paint_chart(img, chart, ppm, m)
    return img, ppm


def plate_extension_mm(definition: dict) -> float:
    """How far the plate reaches beyond the board's bottom margin to hold the colour chart (0: no chart)."""
    chart = definition.get("colour_chart")
    if chart is None:
        return 0.0
    bh = definition["squares"][1] * definition["square_mm"]
    return max(chart["frame_board_mm"][3] + PLATE_MARGIN_MM / 2 - (bh + PLATE_MARGIN_MM), 0.0)


def paint_chart(img: np.ndarray, chart: dict, ppm: float, margin_px: int) -> None:
    """Paint a ColorChecker on the plate image, in place: its black frame and each patch's reference sRGB.

    The patches take their colours from the definition's CIELAB D50 values
    (:func:`workbench.printing.boards.chart_srgb`), so a render carries the chart's truth.
    Pixel (i, j) of the plate image covers board mm [(j - m) / ppm, (j + 1 - m) / ppm]: a
    rectangle is painted on the pixels whose centres it holds.
    """
    from workbench.printing.boards import chart_srgb

    def span(a_mm, b_mm):
        return int(np.ceil(a_mm * ppm + margin_px - 0.5)), int(np.ceil(b_mm * ppm + margin_px - 0.5))

    x0, y0, x1, y1 = chart["frame_board_mm"]
    (j0, j1), (i0, i1) = span(x0, x1), span(y0, y1)
    img[i0:i1, j0:j1] = chart_srgb([[20.0, 0.0, 0.0]])[0]  # the chart's frame: a matte black
    rgb = chart_srgb([p["lab_d50"] for p in chart["patches"]])
    for p, colour in zip(chart["patches"], rgb, strict=True):
        c = np.asarray(p["corners_board_mm"])
        (j0, j1), (i0, i1) = span(c[0, 0], c[1, 0]), span(c[0, 1], c[2, 1])
        img[i0:i1, j0:j1] = colour


def shift_colours(rgb: np.ndarray, shift_lab) -> np.ndarray:
    """Every colour of an sRGB image shifted in CIELAB D50 by (ΔL*, Δa*, Δb*), back to sRGB (clipped); uint8.

    Computed per distinct colour (prints have few), then looked up.
    """
    from workbench.validate.colour import lab_to_linear_srgb, linear_srgb_to_lab, srgb_decode, srgb_encode

    flat = rgb.reshape(-1, 3)
    colours, inverse = np.unique(flat, axis=0, return_inverse=True)
    lab = linear_srgb_to_lab(srgb_decode(colours / 255.0)) + np.asarray(shift_lab, dtype=np.float64)
    out = np.clip(np.round(srgb_encode(np.maximum(lab_to_linear_srgb(lab), 0)) * 255), 0, 255).astype(np.uint8)
    return out[inverse.ravel()].reshape(rgb.shape)


def build_scene(
    V, F, flat_uv_mm, rect_height_mm, print_rgb, dpi, imp: Imperfections, fixture: dict | None, vertex_film=None
) -> Scene:
    """The decorated part (film imperfections applied) and its fixture plate.

    Parameters
    ----------
    V : (#V, 3) float
        Part vertices, mm.
    F : (#F, 3) int
        Part triangles.
    flat_uv_mm : (#V, 2) float
        Flat layout, mm (y up, the design rectangle's bottom-left at the origin).
    rect_height_mm : float
        Height of the design rectangle.
    print_rgb : (rows, cols, 3) uint8
        The print.
    dpi : float
        Its resolution.
    imp : Imperfections
        Film and print errors to apply.
    fixture : dict or None
        Board definition (fixture.json) with ``origin_mm``; None for the part alone.
    vertex_film : (#V,) int, optional
        With several films, the film (0-based) of each vertex, for
        ``imp.film_offsets_mm``.

    Returns
    -------
    Scene
    """
    rows, cols = print_rgb.shape[:2]
    ppm = dpi / 25.4
    # print mm, y down from the trim's top-left corner; film errors are affine there,
    # so transforming the vertices' coordinates transforms every point's exactly
    p = np.stack([flat_uv_mm[:, 0], rect_height_mm - flat_uv_mm[:, 1]], axis=1)
    A = film_transform(imp, (cols / ppm, rows / ppm))
    q = p @ A[:, :2].T + A[:, 2]
    for film, dx, dy in imp.film_offsets_mm:
        if vertex_film is None or not (vertex_film == film - 1).any():
            raise WorkbenchError(f"--film-offset-mm {film}:{dx:g},{dy:g}: the design has no film {film}")
        # the film shows, at print point p, what should be at p - d
        q[vertex_film == film - 1] -= [dx, dy]
    uv = q * ppm - 0.5
    if any(imp.part_offset_mm) or any(imp.part_rotation_deg):
        # the part set down off its outline: every point of it moved rigidly, the plate not
        from workbench.part_motion import part_centre, part_motion

        Rp, tp = part_motion(imp.part_offset_mm, imp.part_rotation_deg, part_centre(V))
        V = V @ Rp.T + tp
    normals = vertex_normals(V, F)
    if any(imp.colour_shift_lab):
        print_rgb = shift_colours(print_rgb, imp.colour_shift_lab)
    if imp.defects:
        # the film's defects live in its texture: every lookup of the print shows them
        print_rgb = apply_defects(print_rgb, dpi, [Defect.parse(d) for d in imp.defects])
    Vs, Fs, uvs, ns, tex = [V], [F], [uv], [normals], [np.zeros(len(F), np.int8)]
    textures = [print_rgb]
    if fixture is not None:
        plate = board_scene(fixture, fixture["origin_mm"])
        Vs.append(plate.V)
        Fs.append(plate.F + len(V))
        uvs.append(plate.uv)
        ns.append(plate.normals)
        tex.append(np.ones(2, np.int8))
        textures.append(plate.textures[0])
    return Scene(
        np.concatenate(Vs),
        np.concatenate(Fs),
        np.concatenate(uvs),
        np.concatenate(ns),
        np.concatenate(tex),
        textures,
        len(F),
    )


def board_scene(definition: dict, origin_mm=(0.0, 0.0, 0.0)) -> Scene:
    """A printed ChArUco board (with a white margin) lying flat, its top edge towards +y.

    With a ``colour_chart`` in the definition, the plate reaches on under the board and
    carries the chart where the definition puts it.

    Board point (x, y) (board frame: x right, y down, mm) is at origin + (x, -y, 0).

    Parameters
    ----------
    definition : dict
        Board definition (``workbench board``).
    origin_mm : (3,) float
        Where the board's top-left corner is.

    Returns
    -------
    Scene
        Two triangles with the board texture: an object of its own (calibration
        photos), or appended to a part as its fixture plate.
    """
    img, bppm = board_texture(definition)
    m = PLATE_MARGIN_MM
    bw = definition["squares"][0] * definition["square_mm"]
    bh = definition["squares"][1] * definition["square_mm"] + plate_extension_mm(definition)
    o = np.asarray(origin_mm, dtype=np.float64)
    corners = np.array([[-m, -m], [bw + m, -m], [bw + m, bh + m], [-m, bh + m]])
    V = np.stack([o[0] + corners[:, 0], o[1] - corners[:, 1], np.full(4, o[2])], axis=1)
    # counter-clockwise seen from above (+z): the board's y axis points to -y
    F = np.array([[0, 3, 2], [0, 2, 1]])
    return Scene(V, F, (corners + m) * bppm - 0.5, np.tile([0.0, 0.0, 1.0], (4, 1)), np.zeros(2, np.int8), [img], 2)


@numba.njit(inline="always", **_JIT)
def _bilinear(img, x, y, c):
    h, w = img.shape[0], img.shape[1]
    x = min(max(x, 0.0), w - 1.0)
    y = min(max(y, 0.0), h - 1.0)
    j = min(int(x), w - 2)
    i = min(int(y), h - 2)
    fx, fy = x - j, y - i
    a = img[i, j, c] * (1 - fx) + img[i, j + 1, c] * fx
    b = img[i + 1, j, c] * (1 - fx) + img[i + 1, j + 1, c] * fx
    return a * (1 - fy) + b * fy


@numba.njit(parallel=True, **_JIT)
def _shade(
    face, P, invz, F, uv, normals, face_tex, tex0, tex1, light, ambient, shading, background, V, eye, gloss, shine, out
):
    H, W = face.shape
    for i in numba.prange(H):
        for j in range(W):
            f = face[i, j]
            if f < 0:
                for c in range(3):
                    out[i, j, c] = background
                continue
            i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
            x, y = float(j), float(i)
            # screen-space barycentrics, then perspective-correct ones (weighted by 1/z)
            w0 = (P[i1, 0] - x) * (P[i2, 1] - y) - (P[i1, 1] - y) * (P[i2, 0] - x)
            w1 = (P[i2, 0] - x) * (P[i0, 1] - y) - (P[i2, 1] - y) * (P[i0, 0] - x)
            w2 = (P[i0, 0] - x) * (P[i1, 1] - y) - (P[i0, 1] - y) * (P[i1, 0] - x)
            q0, q1, q2 = w0 * invz[i0], w1 * invz[i1], w2 * invz[i2]
            s = q0 + q1 + q2
            l0, l1, l2 = q0 / s, q1 / s, q2 / s
            u = l0 * uv[i0, 0] + l1 * uv[i1, 0] + l2 * uv[i2, 0]
            v = l0 * uv[i0, 1] + l1 * uv[i1, 1] + l2 * uv[i2, 1]
            k = 1.0
            if shading:
                nx = l0 * normals[i0, 0] + l1 * normals[i1, 0] + l2 * normals[i2, 0]
                ny = l0 * normals[i0, 1] + l1 * normals[i1, 1] + l2 * normals[i2, 1]
                nz = l0 * normals[i0, 2] + l1 * normals[i1, 2] + l2 * normals[i2, 2]
                nn = np.sqrt(nx * nx + ny * ny + nz * nz)
                d = (nx * light[0] + ny * light[1] + nz * light[2]) / nn
                k = ambient + (1.0 - ambient) * max(d, 0.0)
            spec = 0.0
            if gloss > 0.0 and face_tex[f] == 0:
                # Blinn-Phong: the half vector of light and view directions against the normal
                nx = l0 * normals[i0, 0] + l1 * normals[i1, 0] + l2 * normals[i2, 0]
                ny = l0 * normals[i0, 1] + l1 * normals[i1, 1] + l2 * normals[i2, 1]
                nz = l0 * normals[i0, 2] + l1 * normals[i1, 2] + l2 * normals[i2, 2]
                vx = eye[0] - (l0 * V[i0, 0] + l1 * V[i1, 0] + l2 * V[i2, 0])
                vy = eye[1] - (l0 * V[i0, 1] + l1 * V[i1, 1] + l2 * V[i2, 1])
                vz = eye[2] - (l0 * V[i0, 2] + l1 * V[i1, 2] + l2 * V[i2, 2])
                vn = np.sqrt(vx * vx + vy * vy + vz * vz)
                hx, hy, hz = light[0] + vx / vn, light[1] + vy / vn, light[2] + vz / vn
                hn = np.sqrt(hx * hx + hy * hy + hz * hz) * np.sqrt(nx * nx + ny * ny + nz * nz)
                c_h = (nx * hx + ny * hy + nz * hz) / hn
                if c_h > 0.0:
                    spec = 255.0 * gloss * c_h**shine
            for c in range(3):
                val = _bilinear(tex0, u, v, c) if face_tex[f] == 0 else _bilinear(tex1, u, v, c)
                out[i, j, c] = val * k + spec


def render_ideal(scene: Scene, camera: Camera, imp: Imperfections) -> tuple[np.ndarray, np.ndarray]:
    """A distortion-free image of the scene, linear intensities 0 to 255 (float32).

    Returns
    -------
    image : (H, W, 3) float32
    face : (H, W) int32
        Face seen at each pixel (-1: none).
    """
    xy, z = camera.project(scene.V)
    face, _ = depth_buffer(xy, z, scene.F, camera.width, camera.height)
    with np.errstate(divide="ignore"):
        invz = np.where(z > 0, 1.0 / z, 0.0)
    light = np.asarray(imp.light, dtype=np.float64)
    light = light / np.linalg.norm(light)
    out = np.empty((camera.height, camera.width, 3), dtype=np.float32)
    tex1 = scene.textures[1] if len(scene.textures) > 1 else scene.textures[0][:2, :2]
    _shade(
        face,
        np.ascontiguousarray(xy),
        invz,
        scene.F,
        np.ascontiguousarray(scene.uv),
        scene.normals,
        scene.face_texture,
        scene.textures[0],
        tex1,
        light,
        float(imp.ambient),
        bool(imp.shading),
        float(TABLE_GREY),
        np.ascontiguousarray(scene.V, dtype=np.float64),
        camera.center.astype(np.float64),
        float(imp.gloss),
        float(imp.shininess),
        out,
    )
    return out, face


# the largest area of undistorted image a lens may spread a photo over, in photo areas (a
# fisheye's is about 4)
MAX_LENS_SPREAD = 16.0


def render_photo(scene: Scene, camera: Camera, imp: Imperfections, supersample: int = 2) -> np.ndarray:
    """A synthetic photo: :func:`render_linear`, then the sensor effects of :func:`finish`; (H, W, 3) uint8 RGB."""
    return finish(render_linear(scene, camera, imp, supersample), imp)


def render_linear(scene: Scene, camera: Camera, imp: Imperfections, supersample: int = 2) -> np.ndarray:
    """The scene through the camera and its lens, linear and unquantised.

    The scene is rendered distortion-free at ``supersample`` times the resolution.
    Each photo pixel averages ``supersample²`` samples at its sub-pixel centres; with
    lens distortion each sample is first undistorted (``cv2.undistortPoints``, iterated to 1e-12, on
    a 4-pixel grid interpolated bilinearly) and read from an ideal image large enough
    for the distorted field. So a scene point lands where ``cv2.projectPoints`` puts it.

    Parameters
    ----------
    scene : Scene
        What to render.
    camera : Camera
        Intrinsics and pose; ``imp.distortion`` is the lens.
    imp : Imperfections
        Photo effects (film effects are in the scene already).
    supersample : int
        Samples per pixel along each axis.

    Returns
    -------
    (H, W, 3) float32
        Intensities 0 to 255 (textures of any dtype are sampled as they are).

    Raises
    ------
    WorkbenchError
        The camera sees nothing of the part.
    """
    s = int(supersample)
    W, H = camera.width, camera.height
    dist = np.asarray(imp.distortion, dtype=np.float64)
    if not dist.any():
        ideal, face = render_ideal(scene, camera.scaled(s), imp)
        img = cv2.resize(ideal, (W, H), interpolation=cv2.INTER_AREA) if s > 1 else ideal
    else:
        # where each photo pixel looks in an undistorted image: on a coarse grid first
        step = 4
        gx = np.arange(-step, W + 2 * step, step, dtype=np.float64)
        gy = np.arange(-step, H + 2 * step, step, dtype=np.float64)
        grid = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 1, 2)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        und = cv2.undistortPoints(grid, camera.K, dist, None, None, camera.K, crit).reshape(len(gy), len(gx), 2)
        finite = np.isfinite(und).all()
        lo = np.floor(und.reshape(-1, 2).min(axis=0)) - 2 if finite else np.zeros(2)
        hi = np.ceil(und.reshape(-1, 2).max(axis=0)) + 2 if finite else np.full(2, np.inf)
        spread = float(np.prod(hi - lo) / (W * H))
        if not spread <= MAX_LENS_SPREAD:
            # a p1 of 1 spread a 640 x 480 photo over an undistorted image of 20 GB
            raise WorkbenchError(
                f"distortion {np.round(dist, 6).tolist()}: the lens would spread the photo over "
                f"{'an unbounded' if not np.isfinite(spread) else f'{spread:,.0f} times its'} area of undistorted "
                f"image (at most {MAX_LENS_SPREAD:g}): no lens distorts so much"
            )
        K2 = camera.K.copy()
        K2[:2, 2] -= lo
        big = Camera(K2, camera.R, camera.t, int(hi[0] - lo[0]), int(hi[1] - lo[1]))
        ideal, face = render_ideal(scene, big.scaled(s), imp)
        # photo sub-sample centres, in photo pixels, then in coarse-grid units
        sub = (np.arange(W * s) + 0.5) / s - 0.5
        suby = (np.arange(H * s) + 0.5) / s - 0.5
        cx = ((sub - gx[0]) / step).astype(np.float32)
        cy = ((suby - gy[0]) / step).astype(np.float32)
        mx, my = np.meshgrid(cx, cy)
        ux = cv2.remap(und[..., 0].astype(np.float32), mx, my, cv2.INTER_LINEAR)
        uy = cv2.remap(und[..., 1].astype(np.float32), mx, my, cv2.INTER_LINEAR)
        # undistorted photo pixel -> pixel of the supersampled ideal image
        sx = ((ux - lo[0] + 0.5) * s - 0.5).astype(np.float32)
        sy = ((uy - lo[1] + 0.5) * s - 0.5).astype(np.float32)
        samples = cv2.remap(
            ideal, sx, sy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=(TABLE_GREY,) * 3
        )
        img = cv2.resize(samples, (W, H), interpolation=cv2.INTER_AREA) if s > 1 else samples
    if not (face[(face >= 0)] < scene.n_part_faces).any():
        raise WorkbenchError("the camera sees nothing of the object")
    return img


def finish(img: np.ndarray, imp: Imperfections) -> np.ndarray:
    """Sensor and file effects on a linear image (float, 0 to 255): the light's colour (white
    balance), vignetting, exposure, gamma, blur, noise, quantisation, JPEG."""
    H, W = img.shape[:2]
    out = img.astype(np.float32)
    wb = np.asarray(imp.white_balance, dtype=np.float64)
    if not np.allclose(wb, 1.0):
        # the light's colour multiplies linear light (the image holds sRGB-encoded values)
        from workbench.validate.colour import srgb_decode, srgb_encode

        out = (255.0 * srgb_encode(srgb_decode(out / 255.0) * wb)).astype(np.float32)
    if imp.vignetting:
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
        r2 = ((xx - (W - 1) / 2) ** 2 + (yy - (H - 1) / 2) ** 2) / (((W - 1) / 2) ** 2 + ((H - 1) / 2) ** 2)
        out *= (1.0 - imp.vignetting * r2)[..., None]
    if imp.exposure != 1.0 or imp.gamma != 1.0:
        out = 255.0 * np.clip(out * imp.exposure / 255.0, 0, 1) ** (1.0 / imp.gamma)
    if imp.blur_px > 0:
        out = cv2.GaussianBlur(out, (0, 0), imp.blur_px)
    if imp.noise > 0:
        rng = np.random.default_rng(imp.seed)
        out = out + rng.normal(0.0, imp.noise, out.shape).astype(np.float32)
    rgb = np.clip(np.round(out), 0, 255).astype(np.uint8)
    if imp.jpeg_quality:
        ok, buf = cv2.imencode(
            ".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, int(imp.jpeg_quality)]
        )
        rgb = cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return rgb

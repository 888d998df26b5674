"""Synthetic photos from an independent path tracer: Mitsuba 3 (CPU variant ``scalar_rgb``).

The same :class:`~workbench.render.photo.Scene` (film errors and defects already in its
geometry and texture) and the same :class:`~workbench.camera.Camera` as
:func:`workbench.render.photo.render_photo`, but Mitsuba's own image formation: a
perspective sensor matching ``K``, a box pixel filter over several multi-jittered samples per
pixel, a textured diffuse film (optionally under a rough dielectric coating) lit by
ambient light and a distant lamp, cast shadows and one bounce of interreflection. Only the
lens (Mitsuba has no lens model) and the sensor finish are added afterwards, the lens by
resampling an ideal image through OpenCV's distortion model, the finish by
:func:`workbench.render.photo.finish`.

Conventions checked against the camera model (tests/test_render_mitsuba.py): Mitsuba's
camera frame is OpenCV's turned half a turn about the optical axis (x left, y up, z
forward); its film pixel ``j`` spans ``[j, j + 1]`` where OpenCV's spans
``[j - 0.5, j + 0.5]``; its principal point offset is a fraction of the film's size with
the opposite sign of ``cx - (W - 1) / 2``; a mesh built in Python (not loaded from OBJ) has
no v flip: texture coordinate ``v = 0`` is the bitmap's top row, and texel ``(i, j)``'s
centre is at ``((j + 0.5) / w, (i + 0.5) / h)``.
"""

from __future__ import annotations

import os

import cv2
import numpy as np

from workbench.camera import Camera
from workbench.environment import cache_dir, home_for_a_library
from workbench.errors import WorkbenchError
from workbench.render.imperfections import Imperfections
from workbench.render.photo import TABLE_GREY, Scene, finish

VARIANT = "scalar_rgb"
# PET-G and most thermoforming films: the coating's refractive index for --gloss
FILM_IOR = 1.57
# the ideal image's samples per photo pixel along each axis when it is resampled (lens, fx != fy)
RESAMPLE = 2
# interreflections: camera -> surface -> one bounce -> light
MAX_DEPTH = 3
# the part is lifted this much off its plate (mm): where its rim rests on the plate the two
# surfaces are coplanar, and single-precision ray hits would pick either at random (the
# board's black squares showed through the film there); 1 µm moves its image by
# about 0.005 px at 2000 px across a 300 mm plate, 30 times float32's hit-distance error
LIFT_MM = 1e-3


def load_mitsuba():
    """The ``mitsuba`` module with the ``scalar_rgb`` variant set, imported on first use.

    Raises
    ------
    WorkbenchError
        Mitsuba 3 is not installed (or lacks the variant).
    """
    # Dr.Jit writes its kernel cache into $HOME/.drjit when it loads: the workbench's cache instead
    with home_for_a_library(cache_dir(os.environ) / "mitsuba"):
        try:
            import mitsuba as mi
        except ImportError:
            raise WorkbenchError("--renderer mitsuba needs Mitsuba 3: pip install mitsuba") from None
        if mi.variant() != VARIANT:
            if VARIANT not in mi.variants():
                raise WorkbenchError(f"--renderer mitsuba needs Mitsuba's {VARIANT} variant (have {mi.variants()})")
            mi.set_variant(VARIANT)
    return mi


def roughness_from_shininess(shininess: float) -> float:
    """Beckmann roughness alpha of a Blinn-Phong exponent: ``alpha = sqrt(2 / (n + 2))`` (Walter et al. 2007)."""
    return float(np.sqrt(2.0 / (shininess + 2.0)))


def sensor_to_world(camera: Camera) -> np.ndarray:
    """Mitsuba's camera-to-world matrix for an OpenCV pose; (4, 4) float.

    Mitsuba's camera frame has x left, y up, z forward: OpenCV's x and y negated.
    """
    M = np.eye(4)
    M[:3, 0] = -camera.R[0]
    M[:3, 1] = -camera.R[1]
    M[:3, 2] = camera.R[2]
    M[:3, 3] = camera.center
    return M


def sensor_dict(mi, camera: Camera, spp: int) -> dict:
    """A Mitsuba perspective sensor whose rays are the camera's (square pixels, no skew).

    The horizontal field of view spans the film's full width (pixel edges -0.5 to W - 0.5),
    and the principal point offset is the film-relative distance of ``(cx, cy)`` from the
    film's centre ``((W - 1) / 2, (H - 1) / 2)``, negated (Mitsuba's x and y point left and up).
    """
    K, W, H = camera.K, camera.width, camera.height
    return {
        "type": "perspective",
        "fov_axis": "x",
        "fov": float(np.degrees(2.0 * np.arctan(0.5 * W / K[0, 0]))),
        "principal_point_offset_x": float(-(K[0, 2] - 0.5 * (W - 1)) / W),
        "principal_point_offset_y": float(-(K[1, 2] - 0.5 * (H - 1)) / H),
        "near_clip": 0.1,
        "far_clip": 1e7,
        "to_world": mi.ScalarTransform4f(sensor_to_world(camera).tolist()),
        "film": {
            "type": "hdrfilm",
            "width": int(W),
            "height": int(H),
            "pixel_format": "rgba",
            "rfilter": {"type": "box"},
        },
        "sampler": {"type": "multijitter", "sample_count": int(spp)},
    }


def _bitmap(mi, texture: np.ndarray) -> dict:
    """A Mitsuba bitmap texture of a 0-255 image, read raw (the values are linear reflectances).

    Filtered bilinearly, as the project renderer samples the print, without mip-mapping:
    where the photo sees the print smaller than its own pixels, the pixel's samples average it.
    """
    rgb = np.ascontiguousarray(np.asarray(texture, dtype=np.float32)[..., :3] / 255.0)
    return {"type": "bitmap", "bitmap": mi.Bitmap(rgb), "raw": True, "filter_type": "bilinear", "wrap_mode": "clamp"}


def _mesh(mi, name: str, V, F, uv, normals, bsdf: dict):
    """A Mitsuba triangle mesh with per-vertex texture coordinates and normals."""
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    m = mi.Mesh(name, len(V), len(F), props=props, has_vertex_normals=True, has_vertex_texcoords=True)
    p = mi.traverse(m)
    p["vertex_positions"] = np.ascontiguousarray(V, dtype=np.float32).ravel()
    p["faces"] = np.ascontiguousarray(F, dtype=np.uint32).ravel()
    p["vertex_normals"] = np.ascontiguousarray(normals, dtype=np.float32).ravel()
    p["vertex_texcoords"] = np.ascontiguousarray(uv, dtype=np.float32).ravel()
    p.update()
    return m


def film_bsdf(texture: dict, imp: Imperfections) -> dict:
    """The part's film: diffuse print, or with ``imp.gloss`` the print under a rough dielectric coating.

    The coating's specular reflectance is ``gloss`` (1: a bare Fresnel surface of index
    :data:`FILM_IOR`), its roughness the Beckmann alpha of ``imp.shininess``.
    """
    if imp.gloss > 0:
        bsdf = {
            "type": "roughplastic",
            "distribution": "beckmann",
            "alpha": roughness_from_shininess(imp.shininess),
            "int_ior": FILM_IOR,
            "ext_ior": 1.0,
            "diffuse_reflectance": texture,
            "specular_reflectance": float(imp.gloss),
        }
    else:
        bsdf = {"type": "diffuse", "reflectance": texture}
    return {"type": "twosided", "bsdf": bsdf}


def lights(imp: Imperfections) -> dict:
    """Ambient light (constant, radiance ``ambient``) and a distant lamp (irradiance ``pi (1 - ambient)``).

    A white diffuse surface facing the lamp at angle theta, under open sky, then shows
    ``ambient + (1 - ambient) cos(theta)``: the project renderer's shading, here with
    shadows and interreflections. Without ``imp.shading`` or ``imp.gloss`` the light is
    all ambient (every open surface shows its texture as it is). The ambient light is
    never chosen for light sampling (``sampling_weight`` 0), only found by the BSDF's own
    samples: for a diffuse surface under a uniform sky that estimate has no variance, so
    the Monte Carlo noise is only where something shades the sky (near the part, in
    hollows, and on tilted surfaces whose hemisphere takes in the table): at 4 samples per
    pixel single pixels there are tens of grey levels dark, at 16 a quarter of that. The
    lamp (a delta light) is always the sampled one, at zero power if off.
    """
    lit = bool(imp.shading) or imp.gloss > 0
    ambient = float(imp.ambient) if lit else 1.0
    d = -np.asarray(imp.light, dtype=np.float64)
    d /= np.linalg.norm(d)
    return {
        "ambient": {"type": "constant", "radiance": ambient, "sampling_weight": 0.0},
        "lamp": {"type": "directional", "direction": d.tolist(), "irradiance": np.pi * (1.0 - ambient)},
    }


def scene_dict(mi, scene: Scene, imp: Imperfections, camera: Camera, spp: int) -> dict:
    """The Mitsuba scene: the part, its plate, the table under them, the lights and the sensor."""
    d = {
        "type": "scene",
        # camera rays that meet nothing read as transparent: the table grey goes there
        "integrator": {"type": "path", "max_depth": MAX_DEPTH, "hide_emitters": True},
        "sensor": sensor_dict(mi, camera, spp),
        **lights(imp),
    }
    for k in np.unique(scene.face_texture):
        faces = np.flatnonzero(scene.face_texture == k)
        used, F = np.unique(scene.F[faces], return_inverse=True)
        F = F.reshape(-1, 3)
        th, tw = scene.textures[k].shape[:2]
        # texture pixel coordinates (centres at integers) to Mitsuba's (0 to 1, v down, no flip)
        uv = (scene.uv[used] + 0.5) / [tw, th]
        tex = _bitmap(mi, scene.textures[k])
        is_part = faces[0] < scene.n_part_faces
        bsdf = film_bsdf(tex, imp) if is_part else {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": tex}}
        name = "part" if is_part else f"plate{k}"
        V = scene.V[used] + ([0.0, 0.0, LIFT_MM] if is_part else 0.0)
        d[name] = _mesh(mi, name, V, F, uv, scene.normals[used], bsdf)
    # the table the plate lies on, just below everything, when the camera is above it
    lo, hi = scene.V.min(axis=0), scene.V.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    z = lo[2] - 1e-3 * size
    if camera.center[2] > z:
        c, r = 0.5 * (lo + hi), 50.0 * size
        # Mitsuba's rectangle spans [-1, 1]² in x and y, facing +z
        d["table"] = {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().translate([float(c[0]), float(c[1]), float(z)]).scale([r, r, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": TABLE_GREY / 255.0},
        }
    return d


def ideal_view(camera: Camera, dist, step: int = 4) -> tuple[Camera, np.ndarray | None]:
    """The distortion-free square-pixel camera Mitsuba renders, and where each photo sample reads it.

    Without distortion and with ``fx == fy`` that is the camera itself (no resampling).
    Otherwise the ideal camera has focal length ``max(fx, fy)`` and an image just large
    enough for every undistorted photo point, rendered at :data:`RESAMPLE` times its
    resolution; the photo's ``RESAMPLE²`` sub-sample centres of each pixel are
    undistorted (``cv2.undistortPoints``, iterated to 1e-12, on a ``step``-pixel grid
    interpolated bilinearly) and mapped into it: so a scene point lands where
    ``cv2.projectPoints`` puts it.

    Parameters
    ----------
    camera : Camera
        The photo's camera (pinhole; no skew).
    dist : (5,) float
        Its lens distortion, OpenCV order (k1, k2, p1, p2, k3).
    step : int
        Spacing of the undistortion grid, photo pixels.

    Returns
    -------
    ideal : Camera
        What Mitsuba renders.
    maps : (H * RESAMPLE, W * RESAMPLE, 2) float32 or None
        Pixel of ``ideal`` (centres at integers) of each photo sub-sample; None: the
        render is the photo.
    """
    K, W, H = camera.K, camera.width, camera.height
    dist = np.asarray(dist, dtype=np.float64)
    if abs(K[0, 1]) > 1e-12 * K[0, 0]:
        raise WorkbenchError(f"--renderer mitsuba: K has skew {K[0, 1]:g}; Mitsuba's sensor has square pixels")
    if not dist.any() and abs(K[0, 0] - K[1, 1]) <= 1e-12 * K[0, 0]:
        return camera, None
    f = max(K[0, 0], K[1, 1])
    gx = np.arange(-step, W + 2 * step, step, dtype=np.float64)
    gy = np.arange(-step, H + 2 * step, step, dtype=np.float64)
    grid = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    # normalised undistorted coordinates, times the ideal focal length
    und = f * cv2.undistortPoints(grid, K, dist, None, None, None, crit).reshape(len(gy), len(gx), 2)
    lo = np.floor(und.reshape(-1, 2).min(axis=0)) - 2
    hi = np.ceil(und.reshape(-1, 2).max(axis=0)) + 2
    Ki = np.array([[f, 0.0, -lo[0]], [0.0, f, -lo[1]], [0.0, 0.0, 1.0]])
    s = RESAMPLE
    ideal = Camera(Ki, camera.R, camera.t, int(hi[0] - lo[0]) + 1, int(hi[1] - lo[1]) + 1).scaled(s)
    # photo sub-sample centres in coarse-grid units, their ideal pixel, then at the ideal's scale
    cx = (((np.arange(W * s) + 0.5) / s - 0.5 - gx[0]) / step).astype(np.float32)
    cy = (((np.arange(H * s) + 0.5) / s - 0.5 - gy[0]) / step).astype(np.float32)
    mx, my = np.meshgrid(cx, cy)
    ux = cv2.remap((und[..., 0] - lo[0]).astype(np.float32), mx, my, cv2.INTER_LINEAR)
    uy = cv2.remap((und[..., 1] - lo[1]).astype(np.float32), mx, my, cv2.INTER_LINEAR)
    maps = np.stack([(ux + 0.5) * s - 0.5, (uy + 0.5) * s - 0.5], axis=-1)
    return ideal, maps.astype(np.float32)


def render_ideal_mitsuba(scene: Scene, camera: Camera, imp: Imperfections, spp: int, seed: int) -> np.ndarray:
    """Mitsuba's render of the scene through a pinhole camera, linear 0 to 255; (H, W, 3) float32.

    Pixels where no camera sample meets anything (below the horizon, or with no table
    under a camera looking up) show the table grey, as in the project renderer.
    """
    mi = load_mitsuba()
    sc = mi.load_dict(scene_dict(mi, scene, imp, camera, spp))
    rgba = np.array(mi.render(sc, spp=int(spp), seed=int(seed)), dtype=np.float32)
    # hidden emitters: samples that miss count as zero radiance and zero alpha
    return 255.0 * rgba[..., :3] + (1.0 - rgba[..., 3:4]) * np.float32(TABLE_GREY)


def render_linear_mitsuba(scene: Scene, camera: Camera, imp: Imperfections, spp: int = 16, seed: int = 0) -> np.ndarray:
    """The scene through the camera and its lens, by Mitsuba, linear and unquantised.

    Parameters
    ----------
    scene : Scene
        What to render (:func:`workbench.render.photo.build_scene`).
    camera : Camera
        Intrinsics and pose; ``imp.distortion`` is the lens.
    imp : Imperfections
        Photo effects (film effects are in the scene already); ``shading``, ``light``,
        ``ambient``, ``gloss`` and ``shininess`` set the lights and the film's BSDF.
    spp : int
        Samples per photo pixel (with resampling, ``spp / RESAMPLE²`` per ideal pixel, at
        least 1).
    seed : int
        Mitsuba's sampler seed.

    Returns
    -------
    (H, W, 3) float32
        Intensities 0 to 255.

    Raises
    ------
    WorkbenchError
        Mitsuba is missing, the camera has skew, or it sees nothing of the part.
    """
    if not int(spp) >= 1:
        raise WorkbenchError(f"--spp {spp}: at least 1 sample per pixel")
    check_sees_part(scene, camera)
    ideal, maps = ideal_view(camera, imp.distortion)
    if maps is None:
        return render_ideal_mitsuba(scene, camera, imp, spp, seed)
    img = render_ideal_mitsuba(scene, ideal, imp, max(1, int(round(spp / RESAMPLE**2))), seed)
    samples = cv2.remap(img, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return cv2.resize(samples, (camera.width, camera.height), interpolation=cv2.INTER_AREA)


def render_photo_mitsuba(scene: Scene, camera: Camera, imp: Imperfections, spp: int = 16, seed: int = 0) -> np.ndarray:
    """A synthetic photo by Mitsuba: :func:`render_linear_mitsuba`, then the sensor finish
    (:func:`workbench.render.photo.finish`: vignetting, exposure, gamma, blur, noise, JPEG);
    (H, W, 3) uint8 RGB."""
    return finish(render_linear_mitsuba(scene, camera, imp, spp, seed), imp)


def check_sees_part(scene: Scene, camera: Camera) -> None:
    """Refuse a camera that sees nothing of the part (a z-buffer at a quarter of the resolution)."""
    from workbench.raster import depth_buffer

    small = camera.scaled(0.25)
    xy, z = small.project(scene.V)
    face, _ = depth_buffer(xy, z, scene.F, small.width, small.height)
    if not (face[face >= 0] < scene.n_part_faces).any():
        raise WorkbenchError("the camera sees nothing of the object")

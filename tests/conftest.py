"""Shared test meshes: jittered grids mapped through closed-form conformal maps."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fixtures.make_fixtures import grid_mesh  # noqa: E402

# make test runs the files on every core at once, a file to a worker (pytest-xdist, --dist loadfile,
# --no-loadscope-reorder): the longest go first, or the last to start would run alone at the end.
# Measured with --durations on 2026-12-07 (two loaded cores): these nine took 1,700 of 2,800 s.
LONGEST_FIRST = (
    "test_validate_corpus.py",
    "test_forming.py",
    "test_seating.py",
    "test_validate_colour.py",
    "test_validate.py",
    "test_defects.py",
    "test_part_fusion.py",
    "test_free_outline.py",
    "test_store.py",
)


def pytest_collection_modifyitems(config, items):
    """The longest files first (LONGEST_FIRST), the rest in their order; each file's tests stay together."""
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


@pytest.fixture(autouse=True)
def ctrl_c_as_a_terminal_sends_it():
    """Ctrl-C reaches the tests as a terminal sends it, however the runner was started.

    A suite started by ``nohup`` or with ``&`` has SIGINT ignored, and the command rightly keeps
    it so: every test that sends itself SIGINT then "failed" (197 of the fuzz's 714 signal cases,
    four of ``make test``'s).
    """
    import signal

    ignored = signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    if ignored:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    if ignored:
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def grid_corners(nx: int, ny: int) -> tuple[int, int, int, int]:
    """Corner vertices of :func:`grid_mesh`, counter-clockwise from (0, 0)."""
    return (0, nx - 1, nx * ny - 1, nx * (ny - 1))


@pytest.fixture
def grid():
    return grid_mesh


def annulus_sector(n: int, seed: int = 0, r0=1.0, r1=2.0, t0=0.0, t1=1.0):
    """Planar annular sector meshed as the image of a jittered grid under exp.

    Returns V (#V, 3) on the sector and W (#V, 2): the exact conformal map
    w = log z, which sends the sector onto the rectangle [log r0, log r1] x [t0, t1].
    """
    P, F = grid_mesh(n, n, np.random.default_rng(seed))
    w = np.log(r0) + P[:, 0] * (np.log(r1) - np.log(r0)) + 1j * (t0 + P[:, 1] * (t1 - t0))
    z = np.exp(w)
    return np.stack([z.real, z.imag, np.zeros(len(z))], 1), F, np.stack([w.real, w.imag], 1)


def mercator_patch(n: int, seed: int = 0, radius=50.0, lon=(0.0, 1.2), lat=(-0.6, 0.6)):
    """Sphere patch between two meridians and two parallels; exact map: Mercator (x, y)."""
    P, F = grid_mesh(n, n, np.random.default_rng(seed))
    y0, y1 = (np.log(np.tan(np.pi / 4 + a / 2)) for a in lat)
    x = lon[0] + P[:, 0] * (lon[1] - lon[0])
    y = y0 + P[:, 1] * (y1 - y0)
    phi = 2 * np.arctan(np.exp(y)) - np.pi / 2
    V = radius * np.stack([np.cos(phi) * np.cos(x), np.cos(phi) * np.sin(x), np.sin(phi)], 1)
    return V, F, np.stack([x, y], 1)


def cylinder_patch(n: int, seed: int = 0, radius=40.0, angle=2.0, height=60.0):
    """Cylinder patch, outside decorated; exact map: unrolling (arc length, height) in mm."""
    P, F = grid_mesh(n, n, np.random.default_rng(seed))
    s = P[:, 0] * radius * angle
    h = P[:, 1] * height
    th = s / radius
    V = np.stack([radius * np.sin(th), h, radius * np.cos(th)], 1)
    return V, F, np.stack([s, h], 1)


@pytest.fixture(params=["sqlite", "postgresql"])
def store(request, tmp_path):
    """A new, empty results store: a SQLite file, then a database of a real PostgreSQL server (tests/postgres.py)."""
    from postgres import make_store

    yield from make_store(request.param, tmp_path)


@pytest.fixture(scope="module", params=["sqlite", "postgresql"])
def module_store(request, tmp_path_factory):
    """:func:`store` shared by a module's tests."""
    from postgres import make_store

    yield from make_store(request.param, tmp_path_factory.mktemp("store"))

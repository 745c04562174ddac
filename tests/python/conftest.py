"""Fixtures of the Python package's tests: the repository's scenes, the `raytracer`
binary to compare with, and a local Dask cluster of two worker processes."""

import logging
import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
CORNELL_OBJ = REPO / "examples" / "cornell-box" / "scene.obj"
CORNELL_TOML = REPO / "examples" / "cornell-box" / "scene.toml"

#: The README's camera on the Cornell box, as Python arguments and as flags.
CAMERA = {"fov": 60.0, "look_from": (0.0, 0.7, 1.75), "look_to": (0.0, 0.7, 0.0)}
CAMERA_FLAGS = ["--fov", "60", "--look-from", "0,0.7,1.75", "--look-to", "0,0.7,0"]


def target_dir() -> Path:
    return Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))


@pytest.fixture(scope="session")
def cli() -> Path:
    """The `raytracer` binary of this checkout, built if missing (the README's test
    command builds it first, with `cargo test --release`)."""
    binary = target_dir() / "release" / "raytracer"
    if not binary.exists():
        subprocess.run(["cargo", "build", "--release", "--bin", "raytracer"], cwd=REPO, check=True)
    return binary


@pytest.fixture
def run_cli(cli):
    """Runs `raytracer ARGS...`; returns the completed process (output captured)."""

    def run(*args) -> subprocess.CompletedProcess:
        return subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True)

    return run


@pytest.fixture
def cornell_copy(tmp_path) -> Path:
    """A copy of the Cornell box's files (TOML, OBJ, MTL) in a folder of its own."""
    folder = tmp_path / "cornell"
    shutil.copytree(CORNELL_OBJ.parent, folder)
    return folder


def start_cluster(n_workers: int = 2):
    from distributed import LocalCluster

    return LocalCluster(
        n_workers=n_workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
        silence_logs=logging.ERROR,
    )


@pytest.fixture(scope="session")
def cluster():
    """A local cluster of two worker processes, one thread each, on 127.0.0.1."""
    cluster = start_cluster()
    yield cluster
    cluster.close()


@pytest.fixture
def client(cluster):
    from distributed import Client

    with Client(cluster) as client:
        yield client

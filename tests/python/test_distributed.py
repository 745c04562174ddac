"""raytracer.distributed on a local Dask cluster of two worker processes: the same image
as a local render, bit for bit, from a shared or a shipped scene, when a worker dies,
and from `python -m raytracer.distributed` as from `raytracer render`."""

import gzip
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import raytracer
import raytracer.distributed as rd
from conftest import CAMERA, CAMERA_FLAGS, CORNELL_OBJ, CORNELL_TOML, start_cluster
from test_bindings import bits

pytest.importorskip("distributed")


@pytest.mark.parametrize(
    "options",
    [
        dict(mode="full", spp=4),
        dict(mode="depth"),
        dict(mode="normal"),
        dict(mode="path", spp=2, seed=3),
    ],
)
@pytest.mark.parametrize("tile_size", [7, 16, 100])
def test_the_same_image_as_a_local_render(client, options, tile_size):
    options = dict(width=37, height=23, **CAMERA, **options)
    expected = raytracer.render(CORNELL_OBJ, **options)
    done = []
    linear = rd.render(CORNELL_OBJ, client, tile_size=tile_size, on_tile=lambda *n: done.append(n), **options)
    assert linear.dtype == np.float32 and linear.shape == (23, 37, 3)
    assert np.array_equal(bits(linear), bits(expected))
    tiles = rd.tiles(37, 23, tile_size)
    assert done == [(i + 1, len(tiles)) for i in range(len(tiles))]


def test_tiles_cover_the_image_once():
    for width, height, size in [(37, 23, 8), (64, 64, 64), (1, 1, 5), (130, 2, 64)]:
        cover = np.zeros((height, width), int)
        for x, y, w, h in rd.tiles(width, height, size):
            assert 1 <= w <= size and 1 <= h <= size
            cover[y : y + h, x : x + w] += 1
        assert (cover == 1).all()


def test_options_left_out_keep_the_scene_files_values(client, cornell_copy):
    scene = cornell_copy / "scene.toml"
    scene.write_text(scene.read_text().replace("width = 640", "width = 48").replace("height = 480", "height = 30"))
    for options in ({}, dict(width=24, mode=None), dict(mode="normal", height=10)):
        expected = raytracer.render(scene, **options)
        assert np.array_equal(bits(rd.render(scene, client, tile_size=16, **options)), bits(expected))
    assert rd.render(scene, client).shape == (30, 48, 3)


def test_errors_are_those_of_a_local_render(client, tmp_path):
    with pytest.raises(ValueError) as local:
        raytracer.render(CORNELL_OBJ, fov=0)
    with pytest.raises(ValueError) as remote:
        rd.render(CORNELL_OBJ, client, fov=0)
    assert str(remote.value) == str(local.value)
    missing = tmp_path / "missing.obj"
    with pytest.raises(raytracer.SceneError) as remote:
        rd.render(missing, client)
    assert str(remote.value) == f"{missing}: No such file or directory (os error 2)"
    with pytest.raises(TypeError, match="colour"):
        rd.render(CORNELL_OBJ, client, colour="red")
    with pytest.raises(ValueError, match="tile_size"):
        rd.render(CORNELL_OBJ, client, tile_size=0)


def test_scene_files_are_the_files_a_render_reads(tmp_path, cornell_copy):
    obj = cornell_copy / "scene.obj"
    mtl = cornell_copy / "CornellBox-Sphere.mtl"
    toml = cornell_copy / "scene.toml"
    assert rd.scene_files(obj) == [str(obj), str(mtl)]
    assert rd.scene_files(toml) == [str(toml), str(obj), str(mtl)]
    # Compressed, in another folder, named twice, comments and a missing library.
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    (meshes / "a.obj.gz").write_bytes(
        gzip.compress(b"mtllib one.mtl # two.mtl\nmtllib\tone.mtl ../lib/three.mtl\nv 0 0 0\n")
    )
    scene = tmp_path / "scenes" / "s.toml"
    scene.parent.mkdir()
    scene.write_text('[[mesh]]\nfile = "../meshes/a.obj.gz"\n[[mesh]]\nfile = "../meshes/a.obj.gz"\n')
    assert rd.scene_files(scene) == [
        str(scene),
        str(meshes / "a.obj.gz"),
        str(meshes / "one.mtl"),
        str(tmp_path / "lib" / "three.mtl"),
    ]
    with pytest.raises(OSError):
        rd.scene_files(tmp_path / "missing.toml")


@pytest.fixture
def worker_folder(client, tmp_path):
    """Moves the workers into a folder of their own (restored afterwards): a path under
    /proc/self/cwd then names other files on the workers than on the client, as a path
    that is not shared does."""
    if not os.path.isdir("/proc/self/cwd"):
        pytest.skip("needs /proc/self/cwd")
    folder = tmp_path / "workers"
    folder.mkdir()
    before = client.run(os.getcwd)
    client.run(os.chdir, str(folder))
    yield folder
    for worker, cwd in before.items():
        client.run(os.chdir, cwd, workers=[worker])


def test_a_scene_the_workers_do_not_see_is_shipped(client, cornell_copy, worker_folder, monkeypatch):
    monkeypatch.chdir(cornell_copy)
    scene = "/proc/self/cwd/scene.toml"
    options = dict(width=30, height=20, spp=2)
    expected = raytracer.render(scene, **options)
    # Missing on the workers:
    assert not rd._workers_share(client, scene, "check-1")[0]
    assert np.array_equal(bits(rd.render(scene, client, tile_size=8, **options)), bits(expected))
    # Different on the workers (another colour in the MTL file), so shipped too:
    for name in ("scene.toml", "scene.obj", "CornellBox-Sphere.mtl"):
        (worker_folder / name).write_bytes((cornell_copy / name).read_bytes())
    mtl = worker_folder / "CornellBox-Sphere.mtl"
    mtl.write_text(mtl.read_text().replace("Kd 0.3300 0.0650 0.0500", "Kd 0.1 0.7 0.1", 1))
    assert mtl.read_bytes() != (cornell_copy / "CornellBox-Sphere.mtl").read_bytes()
    assert not rd._workers_share(client, scene, "check-2")[0]
    assert np.array_equal(bits(rd.render(scene, client, tile_size=8, **options)), bits(expected))
    # Told not to ship, the workers read their own files: another image.
    theirs = rd.render(scene, client, ship=False, **options)
    assert not np.array_equal(bits(theirs), bits(expected))
    # The same files: shared.
    mtl.write_bytes((cornell_copy / "CornellBox-Sphere.mtl").read_bytes())
    assert rd._workers_share(client, scene, "check-3")[0]


def test_shipped_scenes_render_the_same_and_name_the_clients_files(client, tmp_path, cornell_copy):
    scene = cornell_copy / "scene.toml"
    # The workers outlive a test: scenes earlier tests left there (not shipped, so
    # without a folder) go first.
    rd.forget(client)
    expected = raytracer.render(scene, width=32, height=24)
    assert np.array_equal(bits(rd.render(scene, client, ship=True, width=32, height=24)), bits(expected))
    # Once forgotten, no worker keeps the scene or its copy of the files.
    folders = sum(client.run(lambda: [j.folder for j in rd._jobs.values()]).values(), [])
    assert folders and all(folder is not None and os.path.isdir(folder) for folder in folders)
    rd.forget(client)
    assert set(client.run(lambda: len(rd._jobs)).values()) == {0}
    assert not any(os.path.exists(folder) for folder in folders)
    # A mesh in a folder of its own, compressed.
    meshes = cornell_copy / "meshes"
    meshes.mkdir()
    (meshes / "box.obj.gz").write_bytes(gzip.compress((cornell_copy / "scene.obj").read_bytes()))
    (meshes / "CornellBox-Sphere.mtl").write_bytes((cornell_copy / "CornellBox-Sphere.mtl").read_bytes())
    scene.write_text(scene.read_text().replace('file = "scene.obj"', 'file = "meshes/box.obj.gz"'))
    assert np.array_equal(bits(rd.render(scene, client, ship=True, width=32, height=24)), bits(expected))
    # Errors name the client's files, not the workers' copies.
    (meshes / "CornellBox-Sphere.mtl").write_text("newmtl x\nKd 1 one 1\n")
    with pytest.raises(raytracer.SceneError) as local:
        raytracer.render(scene)
    with pytest.raises(raytracer.SceneError) as remote:
        rd.render(scene, client, ship=True)
    assert str(remote.value) == str(local.value)


def write_textured_quad(folder, texture_name):
    """A quad with a 2x2 checker texture (four colours) named `texture_name` in its MTL
    file, lit by a point light, in `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "quad.obj").write_text(
        "mtllib quad.mtl\nv -1 -1 -2\nv 1 -1 -2\nv 1 1 -2\nv -1 1 -2\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl checker\nf 1/1 2/2 3/3 4/4\nP 0 0 0 1 1 1\n"
    )
    (folder / "quad.mtl").write_text(f"newmtl checker\nKd 1 1 1\nmap_Kd {texture_name}\n")
    return folder / "quad.obj"


def checker(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    colours = [[(255, 0, 0), (0, 255, 0)], [(0, 0, 255), (255, 255, 0)]]
    raytracer.write_png(np.array(colours, dtype=np.uint8), path)


def test_shipped_scenes_take_their_textures_and_nothing_outside_their_folder(client, tmp_path):
    options = dict(width=16, height=12, fov=90)
    inside = tmp_path / "inside"
    checker(inside / "textures" / "checker.png")
    obj = write_textured_quad(inside, "textures/checker.png")
    expected = raytracer.render(obj, **options)
    assert len(np.unique(expected.reshape(-1, 3), axis=0)) >= 4, "the texture shows"
    assert rd.scene_files(obj) == [str(obj), str(inside / "quad.mtl"), str(inside / "textures" / "checker.png")]
    assert np.array_equal(bits(rd.render(obj, client, ship=True, **options)), bits(expected))
    # Outside the scene's folder: by `..`, by an absolute path, a mesh, a library.
    checker(tmp_path / "elsewhere" / "checker.png")
    outside = tmp_path / "outside"
    cases = {
        "../elsewhere/checker.png": "quad.mtl:3",
        str(tmp_path / "elsewhere" / "checker.png"): "quad.mtl:3",
    }
    for name, line in cases.items():
        obj = write_textured_quad(outside, name)
        assert raytracer.render(obj, **options).shape == (12, 16, 3)
        with pytest.raises(ValueError) as error:
            rd.render(obj, client, ship=True, **options)
        message = str(error.value)
        assert f"it reads {tmp_path / 'elsewhere' / 'checker.png'}, outside its folder {outside}" in message
        assert line in message, message
    toml = outside / "s.toml"
    toml.write_text('[[mesh]]\nfile = "../inside/quad.obj"\n')
    with pytest.raises(ValueError, match=f"it reads {inside / 'quad.obj'}, outside its folder"):
        rd.render(toml, client, ship=True)
    (outside / "quad.obj").write_text("mtllib ../inside/quad.mtl\nv 0 0 0\n")
    with pytest.raises(ValueError, match="quad.obj:1: cannot read material library"):
        rd.render(outside / "quad.obj", client, ship=True)


@pytest.mark.parametrize("ship", [None, True])
def test_workers_keep_a_scene_until_one_of_its_files_changes(client, cornell_copy, ship):
    rd.forget(client)
    scene = cornell_copy / "scene.toml"
    loads = lambda: sum(client.run(lambda: rd._loads).values())  # noqa: E731
    before = loads()
    for look_from in [(0, 0.7, 1.75), (0.3, 0.7, 1.75), (-0.3, 0.9, 1.5)]:
        options = dict(width=24, height=16, look_from=look_from, look_to=(0, 0.7, 0))
        expected = raytracer.render(scene, **options)
        assert np.array_equal(bits(rd.render(scene, client, ship=ship, tile_size=8, **options)), bits(expected))
    # Read once per worker process that took a task, not once per render.
    first = loads() - before
    assert 1 <= first <= 2
    # A changed MTL file (a new colour) is read again, and shows.
    mtl = cornell_copy / "CornellBox-Sphere.mtl"
    mtl.write_text(mtl.read_text().replace("Kd 0.3300 0.0650 0.0500", "Kd 0.1 0.7 0.1", 1))
    expected = raytracer.render(scene, width=24, height=16)
    assert np.array_equal(bits(rd.render(scene, client, ship=ship, tile_size=8, width=24, height=16)), bits(expected))
    assert loads() - before > first
    rd.forget(client)
    assert set(client.run(lambda: len(rd._jobs)).values()) == {0}


class GatedCluster:
    """A fresh local cluster of two worker processes whose renders wait at a gate (a
    test hook of the bindings): each writes `gate.<pid>` and waits until `gate`
    exists. A worker killed while it waits there surely loses the work it was doing:
    found by the gate, not by a clock."""

    def __init__(self, client, gate):
        self.client = client
        self.gate = gate
        self.workers = set(client.run(os.getpid).values())

    def kill_a_worker_during(self, work):
        """Runs `work()` on a thread, kills the first worker found waiting at the gate,
        opens the gate and, once `work` has ended, returns the killed worker's pid."""
        result = {}

        def run():
            try:
                work()
            except BaseException as error:  # noqa: BLE001 - reported by the assertion below
                result["error"] = error

        thread = threading.Thread(target=run)
        thread.start()
        waiting = []
        for _ in range(120_000):
            waiting = [int(m.suffix[1:]) for m in self.gate.parent.glob("gate.*")]
            if waiting or not thread.is_alive():
                break
            time.sleep(0.001)
        assert len(waiting) >= 1 and set(waiting) <= self.workers, (waiting, self.workers, result)
        os.kill(waiting[0], signal.SIGKILL)
        self.gate.touch()
        thread.join()
        assert "error" not in result, result
        return waiting[0]


@pytest.fixture
def gated_cluster(tmp_path, monkeypatch):
    """A :class:`GatedCluster` of its own for a test that kills one of its workers."""
    from distributed import Client

    gate = tmp_path / "gate"
    monkeypatch.setenv("RAYTRACER_TEST_GATE_RENDER", str(gate))
    with start_cluster(2) as cluster, Client(cluster) as client:
        # Only the workers started above wait at the gate, not the local renders.
        monkeypatch.delenv("RAYTRACER_TEST_GATE_RENDER")
        client.wait_for_workers(2)
        yield GatedCluster(client, gate)


def test_a_lost_workers_tiles_are_recomputed(gated_cluster):
    options = dict(width=96, height=72, spp=4, **CAMERA)
    expected = raytracer.render(CORNELL_OBJ, **options)
    result = {}

    def render():
        result["linear"] = rd.render(CORNELL_OBJ, gated_cluster.client, tile_size=8, **options)

    gated_cluster.kill_a_worker_during(render)
    assert np.array_equal(bits(result["linear"]), bits(expected))


def test_render_many_yields_every_frame_once_when_a_worker_is_lost(gated_cluster):
    """A worker killed in the middle of a frame: its task's frames are rendered again
    on the other worker (or on the one the nanny starts), and every frame is yielded
    exactly once, equal to a local render."""
    cameras = [dict(look_from=(x, 0.7, 1.75), look_to=(0.0, 0.7, 0.0)) for x in (-0.4, -0.2, 0.0, 0.2, 0.4, 0.6)]
    common = dict(width=24, height=18, fov=60, spp=2)
    aovs = ["depth", "normal", "object_id"]
    client = gated_cluster.client
    frames = rd.render_many(CORNELL_OBJ, cameras, client, aovs=aovs, frames_per_task=2, **common)
    seen = []
    # Killed while it renders the first frame of a task: that task is lost.
    killed = gated_cluster.kill_a_worker_during(lambda: seen.extend(frames))
    assert killed not in client.run(os.getpid).values()
    assert sorted(index for index, _ in seen) == list(range(len(cameras)))
    for index, frame in seen:
        expected = raytracer.render(CORNELL_OBJ, aovs=aovs, **common, **cameras[index])
        assert set(frame) == set(expected)
        assert all(np.array_equal(frame[name], expected[name]) for name in expected), index


# --- python -m raytracer.distributed ----------------------------------------------------


def run_module(*args, env=None, **kwargs):
    return subprocess.run(
        [sys.executable, "-m", "raytracer.distributed", *map(str, args)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        **kwargs,
    )


@pytest.mark.parametrize("extension", ["exr", "png"])
def test_the_command_writes_what_raytracer_render_writes(tmp_path, run_cli, cluster, extension):
    flags = ["--width", 37, "--height", 23, "--spp", 4, "--fov", 60, "--look-from", "-0.2,0.7,1.75", "--look-to", "0,0.7,0"]
    expected = tmp_path / f"cli.{extension}"
    assert run_cli("render", CORNELL_OBJ, "-o", expected, "-q", *flags).returncode == 0
    out = tmp_path / f"dist.{extension}"
    result = run_module(CORNELL_OBJ, "-o", out, "--scheduler", cluster.scheduler_address, "--tile-size", 10, *flags)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert out.read_bytes() == expected.read_bytes()


def test_the_command_starts_a_local_cluster_without_a_scheduler(tmp_path, run_cli):
    flags = ["--width", 40, "--mode", "depth", *CAMERA_FLAGS]
    expected = tmp_path / "cli.png"
    assert run_cli("render", CORNELL_TOML, "-o", expected, *flags).returncode == 0
    out = tmp_path / "dist.png"
    result = run_module(CORNELL_TOML, "-o", out, "--workers", 2, "-j", 1, "--ship", *flags)
    assert result.returncode == 0, result.stderr
    assert out.read_bytes() == expected.read_bytes()


def test_the_command_fails_as_raytracer_render_does(tmp_path, run_cli, cluster):
    for args in (
        [CORNELL_OBJ, "-o", tmp_path / "x.png", "--width", "0"],
        [CORNELL_OBJ, "-o", tmp_path / "x.jpg"],
        [CORNELL_OBJ, "-o", tmp_path / "missing" / "x.png"],
        [tmp_path / "missing.obj", "-o", tmp_path / "x.png"],
    ):
        expected = run_cli("render", *args)
        result = run_module(*args, "--scheduler", cluster.scheduler_address)
        assert result.returncode == 2, result
        assert result.stderr == expected.stderr
    assert not (tmp_path / "x.png").exists()
    result = run_module(CORNELL_OBJ, "-o", tmp_path / "x.png", "--scheduler", cluster.scheduler_address, "--workers", 2)
    assert result.returncode == 2
    assert result.stderr == "error: --workers and --threads set up a local cluster; not with --scheduler\n"


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_an_interrupt_while_writing_waits_for_the_complete_image(tmp_path, run_cli, cluster, signum):
    flags = ["--width", 20, "--height", 15]
    expected = tmp_path / "cli.png"
    assert run_cli("render", CORNELL_OBJ, "-o", expected, *flags).returncode == 0
    out = tmp_path / "out.png"
    out.write_bytes(b"previous")
    # The library's test hook pauses its atomic write before the rename, after saying
    # so on stderr: the signal then arrives mid-write, at the same step every time.
    env = dict(os.environ, RAYTRACER_TEST_PAUSE_BEFORE_COMMIT="1000")
    process = subprocess.Popen(
        [sys.executable, "-m", "raytracer.distributed", CORNELL_OBJ, "-o", out,
         "--scheduler", cluster.scheduler_address, *map(str, flags)],
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    assert process.stderr.readline().startswith("RAYTRACER_TEST_PAUSE_BEFORE_COMMIT: pausing")
    process.send_signal(signum)
    rest = process.stderr.read()
    assert process.wait(timeout=60) == 0, rest
    assert rest == f"interrupted after {out} was written; it holds the complete new image\n"
    assert out.read_bytes() == expected.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cli.png", "out.png"]


def test_an_interrupt_before_writing_leaves_the_output_as_it_was(tmp_path, cluster):
    out = tmp_path / "out.png"
    out.write_bytes(b"previous")
    # Reading the scene from standard input... no: a scheduler that never answers keeps
    # the command waiting before any tile, deterministically.
    import socket

    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        process = subprocess.Popen(
            [sys.executable, "-m", "raytracer.distributed", CORNELL_OBJ, "-o", out,
             "--scheduler", f"tcp://127.0.0.1:{silent.getsockname()[1]}"],
            stderr=subprocess.PIPE,
            text=True,
        )
        connection, _ = silent.accept()  # the command is connecting: past its checks
        process.send_signal(signal.SIGTERM)
        rest = process.stderr.read()
        assert process.wait(timeout=60) == 130, rest
        connection.close()
    assert rest.endswith(f"interrupted; {out} left as it was\n")
    assert out.read_bytes() == b"previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.png"]


def test_render_many_yields_each_cameras_frame_and_reads_the_scene_once_per_worker(client):
    rd.forget(client)
    loads = lambda: sum(client.run(lambda: rd._loads).values())  # noqa: E731
    before = loads()
    cameras = [
        dict(look_from=(x, 0.7, 1.75), look_to=(0.0, 0.7, 0.0)) for x in (-0.3, 0.0, 0.3, 0.1, -0.1)
    ]
    common = dict(width=24, height=18, fov=60, spp=2)
    aovs = ["depth", "object_id"]
    seen = {}
    for index, frame in rd.render_many(CORNELL_OBJ, cameras, client, aovs=aovs, **common):
        seen[index] = frame
    assert sorted(seen) == list(range(len(cameras)))
    for index, camera in enumerate(cameras):
        expected = raytracer.render(CORNELL_OBJ, aovs=aovs, **common, **camera)
        assert set(seen[index]) == {"color", "depth", "object_id"}
        for name in expected:
            assert np.array_equal(seen[index][name], expected[name]), (index, name)
    # Five frames, two worker processes: the scene is read at most once by each.
    assert loads() - before <= 2
    # Frames in tasks of two (the last task one): each frame once, the same bits.
    grouped = list(rd.render_many(CORNELL_OBJ, cameras, client, aovs=aovs, frames_per_task=2, **common))
    assert sorted(index for index, _ in grouped) == list(range(len(cameras)))
    for index, frame in grouped:
        assert all(np.array_equal(frame[name], seen[index][name]) for name in frame), index
    with pytest.raises(ValueError, match="invalid frames_per_task: 0"):
        next(rd.render_many(CORNELL_OBJ, cameras, client, frames_per_task=0))
    with pytest.raises(TypeError, match="unexpected option 'colour'"):
        next(rd.render_many(CORNELL_OBJ, [dict(colour=1)], client))


# --- render_many(output_dir=...): frames written by the workers -------------------------

RING = [dict(look_from=(x, 0.7, 1.75), look_to=(0.0, 0.7, 0.0)) for x in (-0.4, -0.2, 0.0, 0.2, 0.4, 0.6)]
SMALL = dict(width=24, height=18, fov=60, spp=2)
AOVS = ["depth", "normal", "object_id"]


def assert_written_as_rendered_locally(records, cameras, folder, color_format="png"):
    """Each record's files hold what a local render of its camera gives: the colour's
    file the bytes `raytracer.write_image` writes of the local linear image, each
    output its array; and the folder holds nothing else."""
    assert sorted(records) == list(range(len(cameras)))
    names = set()
    for index, record in records.items():
        expected = raytracer.render(CORNELL_OBJ, aovs=AOVS, **SMALL, **cameras[index])
        files = record["files"]
        assert record["frame"] == index and set(files) == {"color", *AOVS, "camera"}
        local = folder.parent / f"local.{color_format}"
        raytracer.write_image(expected["color"], local)
        assert open(files["color"], "rb").read() == local.read_bytes(), index
        for name in AOVS:
            written = np.load(files[name])
            assert written.dtype == expected[name].dtype and np.array_equal(bits(written), bits(expected[name])), (index, name)
        names |= {os.path.basename(path) for path in files.values()}
    assert {p.name for p in folder.iterdir()} == names


def test_render_many_writes_each_frame_on_the_workers(client, tmp_path):
    folder = tmp_path / "frames"  # made by the workers
    written = rd.render_many(CORNELL_OBJ, RING, client, aovs=AOVS, output_dir=folder, frames_per_task=2, **SMALL)
    records = dict(written)
    assert_written_as_rendered_locally(records, RING, folder)
    # The pose in each frame's JSON file, as a matrix camera with intrinsics, renders
    # what its look-at camera did (within rounding: the matrix is rounded to float32).
    import json

    for index in (0, 3):
        pose = json.loads(open(records[index]["files"]["camera"]).read())
        assert pose == {"frame": index, **records[index]["pose"]}
        K = np.array(pose["K"])
        matrix = raytracer.render(
            CORNELL_OBJ,
            aovs=["depth"],
            camera_to_world=np.array(pose["cam2world_opengl"]),
            intrinsics=(K[0, 0], K[1, 1], K[0, 2], K[1, 2]),
            width=pose["width"],
            height=pose["height"],
            spp=SMALL["spp"],
        )["depth"]
        look_at = np.load(records[index]["files"]["depth"])
        assert np.allclose(matrix, look_at, rtol=1e-4, atol=0), index
    # Linear EXR colour, in a folder that exists.
    exr = tmp_path / "exr"
    exr.mkdir()
    records = dict(rd.render_many(CORNELL_OBJ, RING[:3], client, aovs=AOVS, output_dir=exr, color_format="exr", **SMALL))
    assert_written_as_rendered_locally(records, RING[:3], exr, "exr")


def test_render_many_runs_a_writer_of_ones_own_on_the_workers(client):
    def writer(scene, index, frame, **options):
        return index, os.getpid(), float(frame["depth"].sum()), options["look_from"]

    yielded = dict(rd.render_many(CORNELL_OBJ, RING[:4], client, aovs=["depth"], writer=writer, **SMALL))
    workers = set(client.run(os.getpid).values())
    for index, (said, pid, depth, look_from) in yielded.items():
        expected = raytracer.render(CORNELL_OBJ, aovs=["depth"], **SMALL, **RING[index])["depth"]
        assert said == index and pid in workers and look_from == RING[index]["look_from"]
        assert depth == float(expected.sum())


def test_render_many_refuses_an_output_dir_it_cannot_write_in(client, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("")
    cases = {
        afile: f"invalid output_dir: {afile} is not a folder",
        afile / "below": f"invalid output_dir: cannot write in {afile / 'below'}: Not a directory",
        3: "invalid output_dir: 3 is not a path",
    }
    for output_dir, message in cases.items():
        # Raised by the call, before any frame.
        with pytest.raises(ValueError) as error:
            rd.render_many(CORNELL_OBJ, RING, client, output_dir=output_dir)
        assert str(error.value) == message
    with pytest.raises(ValueError, match="invalid color_format: 'jpg' is not one of png, exr"):
        rd.render_many(CORNELL_OBJ, RING, client, output_dir=tmp_path, color_format="jpg")
    with pytest.raises(ValueError, match="output_dir or writer, not both"):
        rd.render_many(CORNELL_OBJ, RING, client, output_dir=tmp_path, writer=print)
    assert [p.name for p in tmp_path.iterdir()] == ["afile"]


def test_render_many_writes_every_frame_once_when_a_worker_is_lost(gated_cluster, tmp_path):
    """As test_render_many_yields_every_frame_once_when_a_worker_is_lost, the frames
    written by the workers: every index is yielded once, and every file holds what
    a local render gives (a rerun frame replaced whole)."""
    folder = tmp_path / "frames"
    written = rd.render_many(CORNELL_OBJ, RING, gated_cluster.client, aovs=AOVS, output_dir=folder, frames_per_task=2, **SMALL)
    seen = []
    gated_cluster.kill_a_worker_during(lambda: seen.extend(written))
    assert sorted(index for index, _ in seen) == list(range(len(RING)))
    assert_written_as_rendered_locally(dict(seen), RING, folder)


def test_frames_render_with_recycled_pages_and_the_process_settings_come_back(monkeypatch):
    """Under Dask's nanny (MALLOC_TRIM_THRESHOLD_ set), a task's frames render with
    glibc's thresholds raised (its freed buffers' pages reused), and glibc's values
    under that setting (that threshold, a 128 KiB mmap threshold) are restored when
    the task ends, and nothing trimmed; without the setting nothing is touched.
    glibc itself is stood in for: the calls are what is checked."""
    calls = []

    class Libc:
        def mallopt(self, parameter, value):
            calls.append(("mallopt", parameter, value, rd._roomy_tasks))
            return 1

        def malloc_trim(self, pad):
            calls.append(("malloc_trim", pad))
            return 1

    monkeypatch.setattr(rd, "_libc", Libc())
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")
    frames = rd._render_frames([dict(width=8, height=6, **CAMERA)] * 2, 0, "recycled-test", str(CORNELL_OBJ), None)
    rd._forget("recycled-test")
    assert np.array_equal(bits(frames[1]), bits(raytracer.render(CORNELL_OBJ, width=8, height=6, **CAMERA)))
    trim, mmap = rd._M_TRIM_THRESHOLD, rd._M_MMAP_THRESHOLD
    assert calls == [
        ("mallopt", mmap, rd.ROOMY_MMAP_THRESHOLD, 0),
        ("mallopt", trim, rd.ROOMY_TRIM_THRESHOLD, 0),
        ("mallopt", mmap, 128 << 10, 0),
        ("mallopt", trim, 65536, 0),
    ]
    calls.clear()
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_")
    rd._render_frames([dict(width=8, height=6)], 0, "recycled-test", str(CORNELL_OBJ), None)
    rd._forget("recycled-test")
    assert calls == []

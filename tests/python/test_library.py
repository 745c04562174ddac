"""The package behaves as a Python library: Ctrl-C raises KeyboardInterrupt promptly,
warnings go through `warnings`, messages name keywords, progress is reported, images
show in Jupyter, and every render option of the command line has its keyword."""

import _thread
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
import warnings

import numpy as np
import pytest

import raytracer
from conftest import CAMERA, CAMERA_FLAGS, CORNELL_OBJ, CORNELL_TOML


def test_ctrl_c_raises_keyboard_interrupt_and_stops_the_render():
    scene = raytracer.Scene(CORNELL_OBJ)
    # Some twenty seconds of rendering on two cores (more under load): only an
    # interrupt ends it early. Asserted by the rows done, not by a clock, so that a
    # busy machine cannot fail it.
    long = dict(width=256, height=256, mode="path", spp=512, **CAMERA)
    rows = []
    timer = threading.Timer(0.3, _thread.interrupt_main)
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        scene.render(**long, progress=lambda done, total: rows.append(done))
    assert not rows or rows[-1] < 256, rows[-1]
    # The interrupted render has stopped: the next one runs at once and is whole.
    assert scene.render(width=8, height=6, **CAMERA).shape == (6, 8, 3)


def test_sigint_in_a_script_is_a_keyboard_interrupt_not_a_panic(tmp_path):
    """A fresh process (numpy not imported by the script) interrupted while its render
    runs: a KeyboardInterrupt the script catches, no PanicException."""
    gate = tmp_path / "gate"
    script = textwrap.dedent(
        f"""
        import raytracer
        try:
            raytracer.render({str(CORNELL_OBJ)!r}, width=64, height=48, mode="path", spp=64)
        except KeyboardInterrupt:
            print("caught KeyboardInterrupt")
        """
    )
    env = {**os.environ, "RAYTRACER_TEST_GATE_RENDER": str(gate)}
    child = subprocess.Popen(
        [sys.executable, "-c", script], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    marker = tmp_path / f"gate.{child.pid}"
    deadline = time.monotonic() + 30
    while not marker.exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert marker.exists(), "the render never started"
    child.send_signal(signal.SIGINT)
    time.sleep(0.2)
    gate.touch()  # lets the render thread go on: it sees the interrupt and stops
    out, err = child.communicate(timeout=10)
    assert "caught KeyboardInterrupt" in out, err
    assert "Panic" not in err and child.returncode == 0, err


def test_warnings_go_through_the_warnings_module(tmp_path):
    assert issubclass(raytracer.RaytracerWarning, UserWarning)
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 1 1 1\nmap_Kd missing.png\n")
    scene = tmp_path / "s.obj"
    scene.write_text("mtllib m.mtl\nusemtl a\nv 0 0 -2\nv 1 0 -2\nv 0 1 -2\nvt 0 0\nf 1/1 2/1 3/1\n")
    for load in (lambda: raytracer.Scene(scene), lambda: raytracer.render(scene, width=4, height=3)):
        with pytest.warns(raytracer.RaytracerWarning, match="missing.png"):
            load()
    with pytest.warns(raytracer.RaytracerWarning, match="env_strength and env_rotation apply to an environment"):
        raytracer.render(CORNELL_OBJ, width=4, height=3, env_strength=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error", raytracer.RaytracerWarning)
        with pytest.raises(raytracer.RaytracerWarning):
            raytracer.Scene(scene)


def test_messages_name_the_keywords():
    cases = [
        (dict(width=0), "invalid width: 0 is not in 1..=65536"),
        (dict(look_from=(1, 2, 3), look_to=(1, 2, 3)), "invalid look_from/look_to:"),
        (dict(aperture_radius=-1), "invalid aperture_radius:"),
        (dict(env_strength=-1), "invalid env_strength: -1 is not a finite strength of 0 or more"),
        (dict(intrinsics=(0, 1, 2, 3)), "invalid intrinsics:"),
    ]
    for options, message in cases:
        with pytest.raises(ValueError) as error:
            raytracer.render(CORNELL_OBJ, **options)
        assert str(error.value).startswith(message)
        assert "--" not in str(error.value)


def test_progress_is_reported_in_rows_and_a_raising_callback_stops_the_render():
    seen = []
    raytracer.render(CORNELL_OBJ, width=24, height=40, progress=lambda done, total: seen.append((done, total)))
    assert seen[-1] == (40, 40)
    assert all(total == 40 for _, total in seen)
    assert [done for done, _ in seen] == sorted({done for done, _ in seen})

    class Stop(Exception):
        pass

    def stop(done, total):
        raise Stop

    with pytest.raises(Stop):
        raytracer.render(CORNELL_OBJ, width=256, height=256, mode="path", spp=512, progress=stop, **CAMERA)
    with pytest.raises(ValueError, match="progress must be"):
        raytracer.render(CORNELL_OBJ, width=4, progress="yes")


def test_progress_true_draws_a_tqdm_bar(capsys):
    pytest.importorskip("tqdm")
    raytracer.render(CORNELL_OBJ, width=16, height=12, progress=True)
    assert "12/12" in capsys.readouterr().err


def test_images_show_in_jupyter_as_their_png(tmp_path):
    for mode, exposure in (("full", 0.0), ("path", 1.0)):
        image = raytracer.render(CORNELL_OBJ, width=20, height=15, mode=mode, spp=2, exposure=exposure, **CAMERA)
        assert isinstance(image, np.ndarray) and isinstance(image, raytracer.Image)
        assert (image.mode, image.exposure) == (mode, exposure)
        raytracer.write_image(image, tmp_path / "cli-path.png", mode, exposure)
        assert image._repr_png_() == (tmp_path / "cli-path.png").read_bytes()
        assert np.array_equal(image.postprocess(), raytracer.postprocess(image, mode, exposure))
    # Arithmetic gives plain arrays; reductions plain numbers.
    assert type(image * 2) is np.ndarray and isinstance(image.max(), np.floating)
    assert image[0]._repr_png_() is None


def _exr(run_cli, tmp_path, *flags):
    out = tmp_path / "cli.exr"
    result = run_cli("render", CORNELL_OBJ, "-o", out, "-q", "--width", 20, "--height", 15, *CAMERA_FLAGS, *flags)
    assert result.returncode == 0, result.stderr
    return out.read_bytes()


def test_environment_keywords_match_the_flags(tmp_path, run_cli):
    env_png = tmp_path / "sky.png"
    raytracer.write_png(np.arange(8 * 4 * 3, dtype=np.uint8).reshape(4, 8, 3) * 2, env_png)
    cases = [
        (dict(env=(0.5, 0.6, 0.7), env_strength=2), ["--env", "0.5,0.6,0.7", "--env-strength", 2]),
        (dict(env=env_png, env_rotation=30, background=(0.1, 0.2, 0.3)),
         ["--env", env_png, "--env-rotation", 30, "--background", "0.1,0.2,0.3"]),
        (dict(env=str(env_png)), ["--env", env_png]),
    ]
    path = dict(mode="path", spp=2, width=20, height=15, **CAMERA)
    for options, flags in cases:
        linear = raytracer.render(CORNELL_OBJ, **path, **options)
        raytracer.write_image(linear, tmp_path / "mine.exr", "path")
        assert (tmp_path / "mine.exr").read_bytes() == _exr(run_cli, tmp_path, "--mode", "path", "--spp", 2, *flags)
        scene = raytracer.Scene(CORNELL_OBJ, **options)
        assert np.array_equal(scene.render(**path), linear)
    # The environment belongs to the scene, not to one of its renders.
    with pytest.raises(TypeError, match="give them to raytracer.Scene"):
        raytracer.Scene(CORNELL_OBJ).render(env=(1, 1, 1))


def test_default_light_off_matches_no_default_light(tmp_path, run_cli):
    unlit = tmp_path / "unlit.obj"
    unlit.write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3 4\n")
    for mode in ("full", "path"):
        size = dict(width=20, height=15, mode=mode, spp=1)
        linear = raytracer.render(unlit, default_light=False, **size)
        raytracer.write_image(linear, tmp_path / "mine.exr", mode)
        out = tmp_path / "cli.exr"
        flags = ["--width", 20, "--height", 15, "--mode", mode, "--spp", 1, "--no-default-light"]
        assert run_cli("render", unlit, "-o", out, "-q", *flags).returncode == 0
        assert (tmp_path / "mine.exr").read_bytes() == out.read_bytes()
        assert not np.array_equal(linear, raytracer.render(unlit, **size))

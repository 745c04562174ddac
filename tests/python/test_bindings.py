"""The package `raytracer`: renders, tiles, post-processing and files identical to the
command line's, options merged as its flags, its messages, and the GIL released."""

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import raytracer
from conftest import CAMERA, CAMERA_FLAGS, CORNELL_OBJ, CORNELL_TOML

MODES = [("full", 4), ("depth", 1), ("normal", 1), ("path", 4)]


def bits(array: np.ndarray) -> np.ndarray:
    """The array's bit patterns: equal exactly when the values are bit-identical
    (infinity in depth mode, -0.0 and NaN included)."""
    return np.ascontiguousarray(array).view(np.uint32)


def as_keywords(message: str) -> str:
    """A command-line message with each flag named as the Python keyword that sets it:
    what the package says (`--look-from` is `look_from`)."""
    return re.sub(r"(?<![\w-])--([a-z][a-z-]*)", lambda m: m.group(1).replace("-", "_"), message)


def cli_error(result: subprocess.CompletedProcess) -> str:
    assert result.returncode == 2, result
    assert result.stderr.startswith("error: "), result.stderr
    return result.stderr[len("error: ") :].strip()


@pytest.mark.parametrize("mode,spp", MODES)
def test_render_is_the_command_lines_image(tmp_path, run_cli, mode, spp):
    size = {"width": 37, "height": 23}
    linear = raytracer.render(CORNELL_OBJ, mode=mode, spp=spp, **size, **CAMERA)
    assert linear.dtype == np.float32 and linear.shape == (23, 37, 3)
    flags = ["--width", 37, "--height", 23, "--mode", mode, "--spp", spp, *CAMERA_FLAGS]
    exposure = 1.5 if mode == "path" else 0.0
    for extension in ("exr", "png"):
        out = tmp_path / f"cli.{extension}"
        result = run_cli("render", CORNELL_OBJ, "-o", out, "-q", *flags, "--exposure", exposure)
        assert result.returncode == 0, result.stderr
        mine = tmp_path / f"python.{extension}"
        raytracer.write_image(linear, mine, mode, exposure)
        assert mine.read_bytes() == out.read_bytes(), extension
    # The PNG holds exactly what postprocess returns.
    rgb = raytracer.postprocess(linear, mode, exposure)
    assert rgb.dtype == np.uint8 and rgb.shape == (23, 37, 3)
    raytracer.write_png(rgb, tmp_path / "rgb.png")
    assert (tmp_path / "rgb.png").read_bytes() == (tmp_path / "cli.png").read_bytes()


@pytest.mark.parametrize("mode,spp", MODES)
def test_tiles_are_the_same_pixels_as_the_whole_image(mode, spp):
    options = dict(width=37, height=23, mode=mode, spp=spp, **CAMERA)
    whole = raytracer.render(CORNELL_OBJ, **options)
    scene = raytracer.Scene(CORNELL_OBJ)
    merged = np.full_like(whole, np.nan)
    for y in range(0, 23, 8):
        for x in range(0, 37, 8):
            w, h = min(8, 37 - x), min(8, 23 - y)
            part = raytracer.render(scene, tile=(x, y, w, h), **options)
            assert part.shape == (h, w, 3)
            merged[y : y + h, x : x + w] = part
    assert np.array_equal(bits(merged), bits(whole))
    # Through the path too, and a tile the grid does not have.
    part = raytracer.render(str(CORNELL_OBJ), tile=(5, 3, 7, 9), **options)
    assert np.array_equal(bits(part), bits(whole[3:12, 5:12]))


def test_a_scene_read_once_renders_what_the_path_renders():
    scene = raytracer.Scene(CORNELL_TOML)
    assert scene.path == CORNELL_TOML
    assert scene.warnings == []
    for options in (
        {},
        {"width": 50, "spp": 2},
        {"mode": "normal", "look_from": (0.3, 0.5, 1.5)},
        {"mode": "path", "width": 20, "spp": 2, "seed": 7},
    ):
        expected = raytracer.render(CORNELL_TOML, **options)
        assert np.array_equal(bits(scene.render(**options)), bits(expected))
        assert np.array_equal(bits(raytracer.render(scene, **options)), bits(expected))


def test_arguments_left_out_keep_the_scene_files_values(tmp_path, run_cli):
    scene = tmp_path / "scene.toml"
    scene.write_text(
        CORNELL_TOML.read_text()
        .replace("width = 640", "width = 40")
        .replace("height = 480", "height = 30")
        .replace('file = "scene.obj"', f'file = "{CORNELL_OBJ}"')
        .replace("depth = 4", "depth = 2\nspp = 3")
    )
    for options, flags in [
        ({}, []),
        # Explicit None is "not given", as the flag left out.
        (dict(width=None, fov=None, mode=None, spp=None), []),
        # One dimension keeps the file's aspect ratio, as --width alone.
        (dict(width=20), ["--width", 20]),
        (dict(mode="depth", depth=1), ["--mode", "depth", "--depth", 1]),
    ]:
        linear = raytracer.render(scene, **options)
        out = tmp_path / "cli.exr"
        result = run_cli("render", scene, "-o", out, "-q", *flags)
        assert result.returncode == 0, result.stderr
        mine = tmp_path / "mine.exr"
        raytracer.write_image(linear, mine, options.get("mode") or "full")
        assert mine.read_bytes() == out.read_bytes(), options
    assert raytracer.render(scene).shape == (30, 40, 3)
    assert raytracer.render(scene, width=20).shape == (15, 20, 3)
    assert raytracer.Scene(scene).options()["spp"] == 3


def test_a_valid_argument_replaces_a_bad_value_of_the_file(tmp_path, run_cli):
    scene = tmp_path / "bad.toml"
    scene.write_text(f'[camera]\nfov = 180\nwidth = 8\nheight = 6\n\n[[mesh]]\nfile = "{CORNELL_OBJ}"\n')
    with pytest.raises(ValueError) as error:
        raytracer.render(scene)
    assert str(error.value) == cli_error(run_cli("render", scene, "-o", tmp_path / "x.png"))
    assert str(error.value) == f"{scene}:2: camera.fov: 180 is not strictly between 0 and 180"
    assert raytracer.render(scene, fov=60).shape == (6, 8, 3)


@pytest.mark.parametrize(
    "options,flags",
    [
        (dict(width=0), ["--width", "0"]),
        (dict(height=-3), ["--height", "-3"]),
        (dict(width=65536, height=65536), ["--width", "65536", "--height", "65536"]),
        (dict(height=65536), ["--height", "65536"]),
        (dict(fov=180), ["--fov", "180"]),
        (dict(fov=float("nan")), ["--fov", "NaN"]),
        (dict(depth=65), ["--depth", "65"]),
        (dict(spp=0), ["--spp", "0"]),
        (dict(look_to=(0, 0, 0)), ["--look-to", "0,0,0"]),
        (dict(look_from=(1, 2, 3), look_to=(1, 2, 3)), ["--look-from", "1,2,3", "--look-to", "1,2,3"]),
        (dict(up=(0, 0, 0)), ["--up", "0,0,0"]),
        (dict(mode="path", depth=2000), ["--mode", "path", "--depth", "2000"]),
        (dict(exposure=99), ["--exposure", "99"]),
        (dict(seed=-1), ["--seed", "-1"]),
        (dict(seed=2**32), ["--seed", str(2**32)]),
    ],
)
def test_bad_options_are_value_errors_with_the_command_lines_message(tmp_path, run_cli, options, flags):
    with pytest.raises(ValueError) as error:
        raytracer.render(CORNELL_OBJ, **options)
    # The command line's message, naming the keywords instead of the flags.
    expected = as_keywords(cli_error(run_cli("render", CORNELL_OBJ, "-o", tmp_path / "x.png", *flags)))
    assert "--" not in expected
    assert str(error.value) == expected
    with pytest.raises(ValueError) as error:
        raytracer.Scene(CORNELL_OBJ).render(**options)
    assert str(error.value) == expected


@pytest.mark.parametrize(
    "name,content",
    [
        ("missing.obj", None),
        ("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 x 0\nf 1 2 3\n"),
        ("bad.toml", "[camera]\nwidht = 3\n"),
        ("bad.ply", "ply\nformat ascii 1.0\nelement vertex 1\nend_header\n"),
        ("scene.txt", "v 0 0 0\n"),
        ("library.obj", "mtllib bad.mtl\nv 0 0 0\n"),
    ],
)
def test_bad_scenes_are_oserrors_with_the_command_lines_message(tmp_path, run_cli, name, content):
    scene = tmp_path / name
    if content is not None:
        scene.write_text(content)
    (tmp_path / "bad.mtl").write_text("newmtl x\nKd 1 one 1\n")
    expected = cli_error(run_cli("render", scene, "-o", tmp_path / "x.png"))
    for attempt in (lambda: raytracer.render(scene), lambda: raytracer.Scene(scene)):
        with pytest.raises(raytracer.SceneError) as error:
            attempt()
        assert isinstance(error.value, OSError)
        assert str(error.value) == expected


def test_modes_are_named_as_in_scene_files():
    scene = raytracer.Scene(CORNELL_OBJ)
    assert scene.options(mode="normal")["mode"] == "normal"
    # Path mode's own defaults come with it, as on the command line.
    path = scene.options(mode="path")
    assert (path["mode"], path["spp"], path["depth"]) == ("path", 64, 64)
    with pytest.raises(ValueError, match="invalid exposure"):
        raytracer.postprocess(np.zeros((1, 1, 3), np.float32), "path", float("nan"))
    for name in ("fast", "Full", "", 'full"\nwidth = 3'):
        with pytest.raises(ValueError, match="invalid mode: unknown variant"):
            raytracer.render(CORNELL_OBJ, mode=name, width=4)
    with pytest.raises(ValueError, match="unknown variant"):
        raytracer.postprocess(np.zeros((1, 1, 3), np.float32), "fast")


def test_bad_arguments_raise_exceptions_not_crashes(tmp_path):
    small = dict(width=10, height=8)
    cases = [
        (ValueError, "tile 4x4 at \\(8, 0\\) does not lie inside the 10x8 image", dict(tile=(8, 0, 4, 4))),
        (ValueError, "tile 0x4 at \\(0, 0\\) has no pixels", dict(tile=(0, 0, 0, 4))),
        (ValueError, "-1 is not in 0..=4294967295", dict(tile=(-1, 0, 2, 2))),
        (ValueError, "expected \\(x, y, width, height\\), got 3 numbers", dict(tile=(0, 0, 2))),
        (ValueError, "invalid look_from: a vector is three numbers", dict(look_from=(1, 2))),
        (ValueError, "invalid width: .* has too many digits", dict(width=2**80)),
        (TypeError, "width", dict(width="wide")),
        (TypeError, "width", dict(width=1.5)),
        (TypeError, "look_to", dict(look_to="0,0,1")),
    ]
    for exception, message, options in cases:
        with pytest.raises(exception, match=message):
            raytracer.render(CORNELL_OBJ, **{**small, **options})
    for call in (raytracer.render, raytracer.Scene(CORNELL_OBJ).render):
        with pytest.raises(TypeError, match="render\\(\\) got an unexpected keyword argument 'colour'"):
            call(CORNELL_OBJ, colour="red") if call is raytracer.render else call(colour="red")
    with pytest.raises(TypeError, match="options\\(\\) got an unexpected keyword argument 'tile'"):
        raytracer.Scene(CORNELL_OBJ).options(tile=(0, 0, 1, 1))
    # Every option is a keyword of every call; None leaves it to the file or default.
    scene = raytracer.Scene(CORNELL_OBJ)
    left_out = {name: None for name in raytracer.OPTIONS}
    assert scene.options(**left_out) == scene.options()
    assert np.array_equal(scene.render(**{**left_out, "width": 4}), scene.render(width=4))
    with pytest.raises(TypeError):
        raytracer.render(42)
    with pytest.raises(ValueError, match="shape \\(height, width, 3\\)"):
        raytracer.postprocess(np.zeros((4, 4), np.float32).reshape(4, 4, 1))
    with pytest.raises(ValueError, match="at least one pixel"):
        raytracer.write_image(np.zeros((0, 4, 3), np.float32), tmp_path / "x.png")
    with pytest.raises(TypeError):
        raytracer.write_png(np.zeros((2, 2, 3), np.float32), tmp_path / "x.png")


def test_postprocess_takes_any_float_array_and_uses_the_image_wide_maximum():
    linear = raytracer.render(CORNELL_OBJ, width=16, height=12, **CAMERA)
    as_doubles = raytracer.postprocess(linear.astype(np.float64).tolist())
    assert np.array_equal(as_doubles, raytracer.postprocess(linear))
    # A tile alone is tone mapped by its own maximum: not the same pixels.
    bands = [(slice(y, y + 4), slice(0, 16)) for y in (0, 4, 8)]
    dark = next(band for band in bands if linear[band].max() < linear.max())
    assert not np.array_equal(raytracer.postprocess(linear[dark]), raytracer.postprocess(linear)[dark])


def test_images_are_written_atomically_or_not_at_all(tmp_path):
    linear = raytracer.render(CORNELL_OBJ, width=8, height=6)
    out = tmp_path / "out.png"
    out.write_bytes(b"previous")
    assert raytracer.check_output(out) == "png"
    assert raytracer.check_output(tmp_path / "out.EXR") == "exr"
    raytracer.write_image(linear, out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.png"]
    missing = tmp_path / "no" / "folder" / "out.exr"
    for attempt in (lambda: raytracer.write_image(linear, missing), lambda: raytracer.check_output(missing)):
        with pytest.raises(OSError, match=f"cannot write {missing}: folder .* does not exist"):
            attempt()
    with pytest.raises(ValueError, match="unknown image format '.jpg' \\(use .png or .exr\\)"):
        raytracer.write_image(linear, tmp_path / "out.jpg")
    with pytest.raises(ValueError, match="unknown image format"):
        raytracer.check_output(tmp_path / "out.jpg")


GIL_PROBE = textwrap.dedent(
    """
    import os, sys, threading, time
    import numpy, raytracer

    path, gate = sys.argv[1], sys.argv[2]
    scene = raytracer.Scene(path)
    # Once before: a first call's lazy set-up (numpy's C API) must not be what lets
    # the main thread run.
    raytracer.render(path, width=2, height=2)
    scene.intersect([[0, 0.5, 2]], [[0, 0, -1]])
    scene.occluded([[0, 0.5, 2]], [[0, 0, -1]])
    # With a switch interval this long a thread keeps the interpreter until it
    # releases it itself: the main thread runs while a call is under way only if the
    # call released it.
    sys.setswitchinterval(1000)
    calls = [
        ("render(path)", "RENDER", lambda: raytracer.render(path, width=8, height=6)),
        ("Scene.render", "RENDER", lambda: scene.render(width=8, height=6)),
        ("Scene(path)", "LOAD", lambda: raytracer.Scene(path)),
        ("Scene.intersect", "INTERSECT", lambda: scene.intersect([[0, 0.5, 2]], [[0, 0, -1]])),
        ("Scene.occluded", "INTERSECT", lambda: scene.occluded([[0, 0.5, 2]], [[0, 0, -1]])),
    ]
    marker = f"{gate}.{os.getpid()}"
    for name, stage, call in calls:
        # The call writes `marker`, then waits (a minute at most) for `gate` to exist.
        os.environ["RAYTRACER_TEST_GATE_" + stage] = gate
        finished = []
        thread = threading.Thread(target=lambda: (call(), finished.append(True)))
        thread.start()
        while not os.path.exists(marker) and not finished:
            time.sleep(0.001)
        print(name, "held" if finished else "released", flush=True)
        open(gate, "w").close()
        thread.join()
        os.remove(gate)
        os.remove(marker)
        del os.environ["RAYTRACER_TEST_GATE_" + stage]
    """
)


def test_the_gil_is_released_while_loading_rendering_and_tracing(tmp_path):
    result = subprocess.run(
        [sys.executable, "-c", GIL_PROBE, str(CORNELL_OBJ), str(tmp_path / "gate")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[:5] == [
        "render(path) released",
        "Scene.render released",
        "Scene(path) released",
        "Scene.intersect released",
        "Scene.occluded released",
    ]


def test_an_unlit_model_without_a_camera_renders_as_the_command_line_renders_it(tmp_path, run_cli):
    # No light, no camera: the command line frames the model and lights it with the
    # default rig; the path API and a Scene read once must do the same, bit for bit.
    model = tmp_path / "model.obj"
    model.write_text(
        "mtllib m.mtl\nusemtl m\n"
        "v -1 0 0\nv 1 0 0\nv 0 2 0\nv 0 1 1\n"
        "f 1 2 3\nf 1 2 4\nf 2 3 4\nf 3 1 4\n"
    )
    (tmp_path / "m.mtl").write_text("newmtl m\nKa 1 1 1\nKd 0.2 0.6 0.9\n")
    out = tmp_path / "cli.exr"
    result = run_cli("render", model, "-o", out, "-q", "--width", 32, "--height", 24)
    assert result.returncode == 0, result.stderr
    for linear in (
        raytracer.render(model, width=32, height=24),
        raytracer.Scene(model).render(width=32, height=24),
    ):
        mine = tmp_path / "python.exr"
        raytracer.write_image(linear, mine, "full", 0.0)
        assert mine.read_bytes() == out.read_bytes()
        assert linear.max() > 0


def test_under_the_rig_full_mode_takes_four_samples_but_extra_outputs_keep_one(tmp_path):
    # As the command line: an unlit model's first picture multisamples (4 a pixel,
    # unless spp is given), while a render asked for extra outputs (a dataset's
    # depth, normals, ids) keeps one ray through each pixel centre.
    model = tmp_path / "model.obj"
    model.write_text("v -1 0 0\nv 1 0 0\nv 0 2 0\nv 0 1 1\nf 1 2 3\nf 1 2 4\nf 2 3 4\nf 3 1 4\n")
    scene = raytracer.Scene(model)
    size = dict(width=32, height=24)
    assert scene.options(**size)["spp"] == 4
    assert scene.options(**size, spp=1)["spp"] == 1
    assert np.array_equal(bits(scene.render(**size)), bits(scene.render(**size, spp=4)))
    assert not np.array_equal(bits(scene.render(**size)), bits(scene.render(**size, spp=1)))
    outputs = scene.render(**size, aovs=["depth"])
    centres = scene.render(**size, aovs=["depth"], spp=1)
    assert np.array_equal(bits(outputs["depth"]), bits(centres["depth"]))
    assert np.array_equal(bits(outputs["color"]), bits(centres["color"]))


def test_a_scene_lit_by_the_default_rig_moves_its_lights_with_each_camera(tmp_path, run_cli):
    # A Scene keeps its lit copy between renders: each render's rig must be the one
    # of its own camera (the command line's, bit for bit), and the materials lit
    # once (Ka times the ambient light; Ks dropped below Ns 1), not once per render;
    # a physically based metal (MTL's Pm and Pr) reflects the studio in both.
    model = tmp_path / "model.obj"
    model.write_text(
        "mtllib m.mtl\nusemtl m\nv -1 0 0\nv 1 0 0\nv 0 2 0\nv 0 1 1\n"
        "f 1 2 3\nf 1 2 4\nf 2 3 4\nf 3 1 4\nusemtl n\nv -3 -1 -3\nv 3 -1 -3\nv 3 -1 3\nf 5 7 6\n"
    )
    (tmp_path / "m.mtl").write_text(
        "newmtl m\nKa 1 1 1\nKd 0.2 0.6 0.9\nKs 0.5 0.5 0.5\nNs 30\nPm 1\nPr 0.2\nnewmtl n\nKa 1 0 0\nKd 0.7 0.7 0.2\nKs 1 1 1\nNs 0.5\n"
    )
    scene = raytracer.Scene(model)
    cameras = [((0.5, 1.5, 4.0), (0, 1, 0)), ((-3.0, 2.0, 1.0), (0, 0.5, 0)), ((0.5, 1.5, 4.0), (0, 1, 0))]
    for look_from, look_to in cameras:
        flags = ["--width", 24, "--height", 18, "--look-from", ",".join(map(str, look_from)), "--look-to", ",".join(map(str, look_to))]
        out = tmp_path / "cli.exr"
        result = run_cli("render", model, "-o", out, "-q", *flags)
        assert result.returncode == 0, result.stderr
        mine = tmp_path / "python.exr"
        raytracer.write_image(scene.render(width=24, height=18, look_from=look_from, look_to=look_to), mine, "full", 0.0)
        assert mine.read_bytes() == out.read_bytes(), look_from
    # Other modes and the light switched off render the scene as it is.
    assert np.array_equal(
        scene.render(width=24, height=18, default_light=False), raytracer.render(model, width=24, height=18, default_light=False)
    )


def test_full_mode_composites_blended_surfaces_as_the_command_line_does(tmp_path, run_cli):
    # A blended glTF triangle (alpha 0.5) over an opaque one: full mode composites it
    # (the command line's image, bit for bit), lit by the rig or not, whichever
    # render comes first; path mode keeps stochastic transparency.
    import json
    import struct

    corners = [(-1, -1, 0), (1, -1, 0), (0, 1, 0), (-2, -2, -1), (2, -2, -1), (0, 2, -1)]
    (tmp_path / "tri.bin").write_bytes(b"".join(struct.pack("<3f", *c) for c in corners))
    accessor = lambda i: {"bufferView": 0, "byteOffset": 36 * i, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [-2, -2, -1], "max": [2, 2, 0]}
    gltf = {
        "asset": {"version": "2.0"},
        "buffers": [{"uri": "tri.bin", "byteLength": 72}],
        "bufferViews": [{"buffer": 0, "byteLength": 72}],
        "accessors": [accessor(0), accessor(1)],
        "materials": [
            {"alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.2, 0.1, 0.5]}},
            {"pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.6, 0.9, 1]}},
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": i}, "material": i}]} for i in range(2)],
        "nodes": [{"mesh": 0}, {"mesh": 1}],
        "scenes": [{"nodes": [0, 1]}],
    }
    model = tmp_path / "veil.gltf"
    model.write_text(json.dumps(gltf))
    scene = raytracer.Scene(model)
    for light in [False, True, False, True]:
        out = tmp_path / "cli.exr"
        flags = [] if light else ["--no-default-light"]
        result = run_cli("render", model, "-o", out, "-q", "--width", 24, "--height", 18, *flags)
        assert result.returncode == 0, result.stderr
        mine = tmp_path / "python.exr"
        raytracer.write_image(scene.render(width=24, height=18, default_light=light), mine, "full", 0.0)
        assert mine.read_bytes() == out.read_bytes(), light


def test_a_scene_confined_to_a_folder_opens_nothing_outside_it(tmp_path):
    folder = tmp_path / "scene"
    folder.mkdir()
    (tmp_path / "m.mtl").write_text("newmtl m\nKd 1 0 0\n")
    obj = folder / "a.obj"
    obj.write_text("mtllib ../m.mtl\nv 0 0 -1\nv 1 0 -1\nv 0 1 -1\nf 1 2 3\n")
    assert raytracer.Scene(obj).render(width=4, height=3).shape == (3, 4, 3)
    with pytest.raises(raytracer.SceneError, match=f"{obj}:1: .*outside the scene's folder {folder}"):
        raytracer.Scene(obj, confined_to=folder)
    # A texture outside is a warning, and the surface renders without it.
    (tmp_path / "t.png").write_bytes(b"not read")
    (folder / "m.mtl").write_text(f"newmtl m\nKd 1 0 0\nmap_Kd {tmp_path / 't.png'}\n")
    obj.write_text("mtllib m.mtl\nv 0 0 -1\nv 1 0 -1\nv 0 1 -1\nusemtl m\nf 1 2 3\n")
    warnings = raytracer.Scene(obj, confined_to=folder).warnings
    assert any(f"{folder / 'm.mtl'}:3: cannot read texture" in w and "outside the scene's folder" in w for w in warnings)
    with pytest.raises(raytracer.SceneError, match="missing"):
        raytracer.Scene(obj, confined_to=tmp_path / "missing")


def test_denoise_needs_the_denoiser_as_the_command_lines_flag_does(tmp_path, run_cli):
    """`denoise=` is `--denoise`: in a build without the denoiser (CI's), an error
    naming the keyword before any work, as the command line's is; `False` renders as
    without it."""
    size = {"width": 16, "height": 12, "mode": "path", "spp": 2}
    flags = ["--width", 16, "--height", 12, "--mode", "path", "--spp", 2, *CAMERA_FLAGS]
    result = run_cli("render", CORNELL_OBJ, "-o", tmp_path / "cli.png", "-q", "--denoise", *flags)
    if result.returncode == 0:
        pytest.skip("built with the denoiser")
    assert "no denoiser" in result.stderr
    for scene in (CORNELL_OBJ, raytracer.Scene(CORNELL_OBJ)):
        with pytest.raises(ValueError, match=r"^denoise=True: .* without the denoiser"):
            raytracer.render(scene, denoise=True, **size, **CAMERA)
        with pytest.raises(TypeError, match="denoise must be True or False"):
            raytracer.render(scene, denoise="yes", **size, **CAMERA)
    plain = raytracer.render(CORNELL_OBJ, **size, **CAMERA)
    assert np.array_equal(raytracer.render(CORNELL_OBJ, denoise=False, **size, **CAMERA), plain)


def test_tonemap_and_lens_keywords_are_the_command_lines(tmp_path, run_cli):
    size = {"width": 20, "height": 15, "mode": "path", "spp": 2}
    lens = {"aperture_radius": 0.05, "focus_distance": 1.5}
    linear = raytracer.render(CORNELL_OBJ, **size, **lens, **CAMERA)
    flags = ["--width", 20, "--height", 15, "--mode", "path", "--spp", 2, *CAMERA_FLAGS]
    flags += ["--aperture-radius", 0.05, "--focus-distance", 1.5, "--tonemap", "agx"]
    out = tmp_path / "cli.png"
    result = run_cli("render", CORNELL_OBJ, "-o", out, "-q", *flags)
    assert result.returncode == 0, result.stderr
    mine = tmp_path / "python.png"
    raytracer.write_image(linear, mine, "path", 0.0, "agx")
    assert mine.read_bytes() == out.read_bytes()
    # The default tone map is khronos-neutral; tone maps differ.
    default = raytracer.postprocess(linear, "path")
    assert np.array_equal(default, raytracer.postprocess(linear, "path", 0.0, "khronos-neutral"))
    assert not np.array_equal(default, raytracer.postprocess(linear, "path", 0.0, "agx"))
    with pytest.raises(ValueError, match="invalid tonemap"):
        raytracer.postprocess(linear, "path", 0.0, "filmic")
    with pytest.raises(ValueError, match="invalid aperture_radius"):
        raytracer.render(CORNELL_OBJ, aperture_radius=-1, **CAMERA)
    info = raytracer.Scene(CORNELL_OBJ).options(tonemap="ACES", aperture_radius=0.25, **CAMERA)
    assert (info["tonemap"], info["aperture_radius"], info["focus_distance"]) == ("aces", 0.25, 1.75)

"""Every render option of the table (``raytracer::options::OPTIONS``, exported as
``raytracer._raytracer._option_table()``) reaches the three front ends: the same
value given as a flag, as a TOML key and as a Python keyword renders the same image,
and the same value out of range is refused by all three with the same message after
their name of the option."""

import warnings

import pytest

import raytracer
from conftest import CORNELL_OBJ

TABLE = raytracer._raytracer._option_table()

#: The base scene: the Cornell box, small, in path mode with one sample per pixel.
BASE = {
    "camera.width": "8",
    "camera.height": "6",
    "camera.fov": "60",
    "camera.look_from": "[0, 0.7, 1.75]",
    "camera.look_to": "[0, 0.7, 0]",
    "render.mode": '"path"',
    "render.spp": "1",
    "render.depth": "3",
}


def toml_key(option):
    """The TOML key the example sets: a colour environment is `color`."""
    if option["kind"] == "file_or_colour":
        return "environment.color"
    return option["toml"]


def spellings(option, text):
    """`text` (as the command line spells it) as a TOML value and a Python value."""
    kind = option["kind"]
    if kind == "whole":
        return text, int(text)
    if kind == "number":
        return text, float(text)
    if kind == "choice":
        return f'"{text}"', text
    if kind == "switch_off":
        return "false", False
    numbers = [float(n) for n in text.split(",")]
    if kind == "matrix":
        rows = [numbers[i : i + 4] for i in range(0, 16, 4)]
        return str(rows), rows
    return str(numbers), tuple(numbers)


def scene_file(folder, name, values, base=BASE):
    """A TOML scene of the `base` values updated by `values` (dotted keys)."""
    tables = {}
    for key, value in {**base, **values}.items():
        section, field = key.split(".")
        tables.setdefault(section, []).append(f"{field} = {value}")
    # A camera matrix replaces look_from and look_to.
    if "camera.matrix" in values:
        tables["camera"] = [t for t in tables["camera"] if not t.startswith("look_")]
    text = f'[[mesh]]\nfile = "{CORNELL_OBJ.as_posix()}"\n'
    for section, lines in tables.items():
        text += f"[{section}]\n" + "\n".join(lines) + "\n"
    path = folder / f"{name}.toml"
    path.write_text(text)
    return path


def bad_value(option):
    """A value just outside the option's range, as the command line spells it."""
    kind, low, high = option["range"]
    if option["python"] == "depth":
        # The table's range is full mode's; the base scene is in path mode.
        return "1025"
    if kind in ("whole", "within"):
        return str(int(high) + 1)
    if kind == "open":
        return str(int(high))
    return {"not_negative": "-1", "positive": "0", "finite": "inf"}[kind]


@pytest.mark.parametrize("option", TABLE, ids=[o["python"] for o in TABLE])
def test_every_option_reaches_every_front_end_alike(option, tmp_path, run_cli):
    keyword, flag, key = option["python"], option["flag"], toml_key(option)
    assert key is not None, "every option has a TOML key"
    toml_value, python_value = spellings(option, option["example"])
    # A width or height alone keeps the aspect ratio of the other's source: of the
    # defaults (640x480) when the file sets neither, as here for these two.
    sizes = ("camera.width", "camera.height")
    common = {k: v for k, v in BASE.items() if key not in sizes or k not in sizes}
    base = scene_file(tmp_path, "base", {}, common)
    keyed = scene_file(tmp_path, "keyed", {key: toml_value}, common)

    # The same value: the same image from the TOML key, the keyword and the flag.
    from_toml = tmp_path / "toml.png"
    done = run_cli("render", keyed, "-o", from_toml)
    assert done.returncode == 0, done.stderr
    if flag is not None:
        from_flag = tmp_path / "flag.png"
        value = [] if option["kind"] == "switch_off" else [option["example"]]
        done = run_cli("render", base, "-o", from_flag, flag, *value)
        assert done.returncode == 0, done.stderr
        assert from_flag.read_bytes() == from_toml.read_bytes(), f"{flag} and {key} differ"
    with warnings.catch_warnings():
        # An environment's strength or rotation without an environment is a warning.
        warnings.simplefilter("ignore", raytracer.RaytracerWarning)
        linear = raytracer.render(base, **{keyword: python_value})
    # Post-processed as the keyword says (exposure, tone map), as the command line does.
    given = {} if option["scene"] else {keyword: python_value}
    settings = raytracer.Scene(base).options(**given)
    from_python = tmp_path / "python.png"
    raytracer.write_image(linear, from_python, settings["mode"], settings["exposure"], settings["tonemap"])
    assert from_python.read_bytes() == from_toml.read_bytes(), f"{keyword}= and {key} differ"

    if option["range"] is None:
        return
    # The same value out of range: the same message after each one's name for it.
    bad = bad_value(option)
    toml_bad, python_bad = spellings(option, bad)
    with pytest.raises(ValueError) as python_error:
        raytracer.render(base, **{keyword: python_bad})
    prefix = f"invalid {keyword}: "
    assert str(python_error.value).startswith(prefix), python_error.value
    message = str(python_error.value)[len(prefix) :]
    done = run_cli("render", scene_file(tmp_path, "bad", {key: toml_bad}, common), "-o", tmp_path / "x.png")
    assert done.returncode == 2
    assert done.stderr.strip().endswith(f": {key}: {message}"), done.stderr
    done = run_cli("render", base, "-o", tmp_path / "x.png", f"{flag}={bad}")
    assert done.returncode == 2
    assert f"invalid {flag}: {message}" in done.stderr, done.stderr

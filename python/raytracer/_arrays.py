"""Scenes from arrays (``Scene.from_arrays``) and from trimesh objects
(``Scene.from_trimesh``): the arrays are checked here with numpy, each error naming the
argument and its first bad element; materials, lights and the environment become a
TOML document that the library's one TOML reader reads, so their keys and checks are
the scene format's. Images given as arrays are written to a temporary folder for the
library's texture reader, and the folder removed once the scene is built.

Transforms: a mesh placed more than once is stored once, its copies instances of it
(the two-level BVH); the geometry reaches the library as arrays, never as text.
"""

import json
import math
import os
import tempfile

import numpy as np

MESH_KEYS = ("vertices", "faces", "normals", "uvs", "colors", "material", "transforms", "name")
TEXTURE_KEYS = ("map_Kd", "base_color_texture")


def _array(value, name: str, columns: int, kinds: str, what: str) -> np.ndarray:
    try:
        array = np.asarray(value)
    except Exception as error:  # noqa: BLE001 - anything numpy cannot take
        raise ValueError(f"{name} must be {what}: {error}") from None
    if array.dtype.kind not in kinds or (array.size == 0 and array.ndim != 2):
        raise ValueError(f"{name} must be {what}, not an array of {array.dtype}")
    if array.ndim != 2 or array.shape[1] != columns:
        raise ValueError(f"{name} must have the shape (n, {columns}), not {array.shape}")
    return array


def _finite(array: np.ndarray, name: str) -> None:
    bad = ~np.isfinite(array).all(axis=1)
    if bad.any():
        row = int(np.argmax(bad))
        raise ValueError(f"{name}[{row}] is {array[row].tolist()}: not finite")


def _transforms(value, name: str) -> np.ndarray:
    matrices = np.asarray(value, dtype=np.float64)
    if matrices.shape == (4, 4):
        matrices = matrices[None]
    if matrices.ndim != 3 or matrices.shape[1:] != (4, 4):
        raise ValueError(f"{name} must have the shape (k, 4, 4) or (4, 4), not {matrices.shape}")
    if len(matrices) == 0:
        raise ValueError(f"{name} holds no matrix: give at least one, or leave the mesh out")
    for k, matrix in enumerate(matrices):
        if not np.isfinite(matrix).all():
            raise ValueError(f"{name}[{k}] has a value that is not finite")
        if not np.array_equal(matrix[3], [0, 0, 0, 1]):
            raise ValueError(f"{name}[{k}]: the last row is {matrix[3].tolist()}, not [0, 0, 0, 1]")
        if abs(np.linalg.det(matrix[:3, :3])) < 1e-12:
            raise ValueError(f"{name}[{k}] is singular")
    return matrices


def _toml_value(value, name: str) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else ("-inf" if v == -math.inf else repr(v)))
    if isinstance(value, (str, os.PathLike)):
        return json.dumps(os.fspath(value))
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(v, name) for v in np.asarray(value).tolist()) + "]"
    raise ValueError(f"{name}: {value!r} is not a number, a string, a boolean or a list of numbers")


def _table(header: str, values: dict, name: str) -> str:
    if not isinstance(values, dict):
        raise ValueError(f"{name} must be a dict of the TOML keys, not {type(values).__name__}")
    lines = [header]
    for key, value in values.items():
        if not isinstance(key, str):
            raise ValueError(f"{name}: the key {key!r} is not a string")
        lines.append(f"{json.dumps(key)} = {_toml_value(value, f'{name}[{key!r}]')}")
    return "\n".join(lines) + "\n"


def _image_file(value, folder: str, stem: str, name: str) -> str:
    """A texture given as a path stays one; a numpy image is written to `folder`."""
    if isinstance(value, (str, os.PathLike)):
        return os.path.abspath(os.fspath(value))
    from . import write_image, write_png

    image = np.asarray(value)
    if image.ndim != 3 or image.shape[2] != 3 or image.size == 0:
        raise ValueError(f"{name} must be an image file's path or an (h, w, 3) array, not of the shape {image.shape}")
    if image.dtype == np.uint8:
        path = os.path.join(folder, f"{stem}.png")
        write_png(np.ascontiguousarray(image), path)
    elif image.dtype.kind == "f":
        _finite(image.reshape(-1, 3), name)
        path = os.path.join(folder, f"{stem}.exr")
        write_image(image.astype(np.float32), path)
    else:
        raise ValueError(f"{name} must be uint8 (sRGB) or float (linear), not {image.dtype}")
    return path


def _colors(value, name, n):
    """Vertex colours as (n, 3) linear floats: (n, 3) or (n, 4) (alpha dropped),
    uint8 read as 0..255 and uint16 as 0..65535, floats as they are (not negative)."""
    colors = np.asarray(value)
    if colors.ndim != 2 or colors.shape[1] not in (3, 4) or colors.dtype.kind not in "fiu":
        raise ValueError(f"{name} must be an (n, 3) or (n, 4) array of numbers, not {colors.dtype} {colors.shape}")
    if len(colors) != n:
        raise ValueError(f"{name} has {len(colors)} rows, not one per vertex ({n})")
    colors = colors[:, :3]
    if colors.dtype == np.uint8 or colors.dtype == np.uint16:
        colors = colors / np.iinfo(colors.dtype).max
    colors = colors.astype(np.float64)
    _finite(colors, name)
    bad = (colors < 0).any(axis=1)
    if bad.any():
        row = int(np.argmax(bad))
        raise ValueError(f"{name}[{row}] is {colors[row].tolist()}: colours must not be negative")
    return colors


def compose(meshes, lights, environment):
    """The TOML document, its folder (kept alive by the fourth item, a temporary
    folder), and each mesh as [vertices, faces, normals, uvs, material name, texture
    path, name, transforms, colours] of checked, contiguous arrays: transforms a
    (k, 4, 4) array of the instances placing the mesh, or None (one transform applied
    to the vertices); colours (n, 3) linear or None."""
    folder = tempfile.TemporaryDirectory(prefix="raytracer-arrays-")
    document = []
    out = []
    meshes = [] if meshes is None else meshes
    if isinstance(meshes, dict):
        meshes = [meshes]
    for k, mesh in enumerate(meshes):
        name = f"meshes[{k}]"
        if not isinstance(mesh, dict):
            raise ValueError(f"{name} must be a dict (vertices, faces, ...), not {type(mesh).__name__}")
        unknown = [key for key in mesh if key not in MESH_KEYS]
        if unknown:
            raise ValueError(f"{name}: unknown key {unknown[0]!r} (one of {', '.join(MESH_KEYS)})")
        for required in ("vertices", "faces"):
            if required not in mesh:
                raise ValueError(f"{name} has no {required!r}")
        vertices = _array(mesh["vertices"], f"{name}['vertices']", 3, "fiu", "an (n, 3) array of numbers")
        _finite(vertices, f"{name}['vertices']")
        n = len(vertices)
        faces = _array(mesh["faces"], f"{name}['faces']", 3, "iu", "an (m, 3) array of integers")
        bad = ((faces < 0) | (faces >= n)).any(axis=1)
        if bad.any():
            row = int(np.argmax(bad))
            raise ValueError(f"{name}['faces'][{row}] is {faces[row].tolist()}: vertex indices must be in 0..{n}")
        normals = uvs = None
        if mesh.get("normals") is not None:
            normals = _array(mesh["normals"], f"{name}['normals']", 3, "fiu", "an (n, 3) array of numbers")
            _finite(normals, f"{name}['normals']")
            if len(normals) != n:
                raise ValueError(f"{name}['normals'] has {len(normals)} rows, not one per vertex ({n})")
        if mesh.get("uvs") is not None:
            uvs = _array(mesh["uvs"], f"{name}['uvs']", 2, "fiu", "an (n, 2) array of numbers")
            _finite(uvs, f"{name}['uvs']")
            if len(uvs) != n:
                raise ValueError(f"{name}['uvs'] has {len(uvs)} rows, not one per vertex ({n})")
        colors = None
        if mesh.get("colors") is not None:
            colors = _colors(mesh["colors"], f"{name}['colors']", n)
        material = texture = None
        if mesh.get("material") is not None:
            values = mesh["material"]
            if not isinstance(values, dict):
                raise ValueError(f"{name}['material'] must be a dict of the TOML material keys")
            values = dict(values)
            maps = [key for key in TEXTURE_KEYS if values.get(key) is not None]
            for key in TEXTURE_KEYS:
                values.pop(key, None)
            if maps:
                texture = _image_file(mesh["material"][maps[0]], folder.name, f"texture{k}", f"{name}['material'][{maps[0]!r}]")
            material = name
            document.append(_table(f"[materials.{json.dumps(name)}]", values, f"{name}['material']"))
        matrices = None
        if mesh.get("transforms") is not None:
            matrices = _transforms(mesh["transforms"], f"{name}['transforms']")
        out.append([vertices, faces, normals, uvs, material, texture, str(mesh.get("name", name)), matrices, colors])
    # A mesh placed more than once is stored once and placed by instances. Then every
    # mesh is (placed by the identity if it has no transform): the scene is two-level
    # anyway, and object ids then follow the meshes, copy after copy. Otherwise each
    # mesh is placed into one level, its one transform applied here.
    instanced = any(entry[7] is not None and len(entry[7]) > 1 for entry in out)
    for entry in out:
        vertices, normals, matrices = entry[0], entry[2], entry[7]
        if instanced:
            entry[7] = np.eye(4)[None] if matrices is None else np.ascontiguousarray(matrices)
        elif matrices is not None:
            m = matrices[0]
            entry[0] = vertices.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
            if normals is not None:
                entry[2] = normals @ np.linalg.inv(m[:3, :3])
            entry[7] = None
        # Copied only when not already the dtype and layout the library reads.
        entry[0] = np.ascontiguousarray(entry[0], dtype=np.float32)
        entry[1] = np.ascontiguousarray(entry[1], dtype=np.uint32)
        entry[2] = None if entry[2] is None else np.ascontiguousarray(entry[2], dtype=np.float32)
        entry[3] = None if entry[3] is None else np.ascontiguousarray(entry[3], dtype=np.float32)
        entry[8] = None if entry[8] is None else np.ascontiguousarray(entry[8], dtype=np.float32)
    for k, light in enumerate([] if lights is None else lights):
        document.append(_table("[[light]]", light, f"lights[{k}]"))
    if environment is not None:
        if isinstance(environment, dict) and environment.get("file") is not None:
            environment = dict(environment)
            environment["file"] = _image_file(environment["file"], folder.name, "environment", "environment['file']")
        document.append(_table("[environment]", environment, "environment"))
    return "\n".join(document), folder.name, out, folder


def from_trimesh(obj):
    """``Scene.from_trimesh``: see its documentation."""
    from . import Scene

    try:
        import trimesh
    except ImportError as error:
        raise ImportError("Scene.from_trimesh needs trimesh (pip install trimesh)") from error
    if isinstance(obj, trimesh.Scene):
        placed = []
        for node in obj.graph.nodes_geometry:
            transform, geometry = obj.graph[node]
            placed.append((obj.geometry[geometry], transform))
    elif isinstance(obj, trimesh.Trimesh):
        placed = [(obj, None)]
    else:
        raise ValueError(f"from_trimesh takes a trimesh.Trimesh or trimesh.Scene, not {type(obj).__name__}")
    meshes = []
    for mesh, transform in placed:
        if not isinstance(mesh, trimesh.Trimesh):
            continue  # point clouds and paths have no surface
        entry = {"vertices": mesh.vertices, "faces": mesh.faces}
        if "vertex_normals" in mesh._cache:
            entry["normals"] = mesh.vertex_normals
        if transform is not None:
            entry["transforms"] = transform
        visual = mesh.visual
        material = getattr(visual, "material", None)
        if getattr(visual, "uv", None) is not None and len(visual.uv) == len(mesh.vertices):
            entry["uvs"] = visual.uv
        # Per-vertex colours (a PLY file's, say): 8-bit RGBA, which `colors` reads as
        # the PLY reader reads `uchar` channels (divided by 255). Face colours have
        # no counterpart in the scene and are left out.
        if getattr(visual, "kind", None) == "vertex":
            entry["colors"] = visual.vertex_colors
        if material is not None:
            entry["material"] = _trimesh_material(material)
            if "uvs" not in entry:
                entry["material"].pop("map_Kd", None)
                entry["material"].pop("base_color_texture", None)
        meshes.append(entry)
    return Scene.from_arrays(meshes=meshes)


def _trimesh_material(material) -> dict:
    """The TOML material keys of a trimesh material."""
    import trimesh.visual.material as materials

    def colour(rgba):
        return (np.asarray(rgba, dtype=np.float64)[:3] / 255.0).tolist()

    def image(picture):
        return None if picture is None else np.asarray(picture.convert("RGB"))

    if isinstance(material, materials.PBRMaterial):
        out = {}
        if material.baseColorFactor is not None:
            out["base_color"] = colour(material.baseColorFactor)
        if material.metallicFactor is not None:
            out["metallic"] = float(material.metallicFactor)
        if material.roughnessFactor is not None:
            out["roughness"] = float(material.roughnessFactor)
        if material.emissiveFactor is not None and np.any(material.emissiveFactor):
            out["emission"] = np.asarray(material.emissiveFactor, dtype=np.float64).tolist()
        if not out:
            out["base_color"] = [1.0, 1.0, 1.0]
        out["base_color_texture"] = image(material.baseColorTexture)
        return out
    out = {}
    for key, attribute in (("Ka", "ambient"), ("Kd", "diffuse"), ("Ks", "specular")):
        value = getattr(material, attribute, None)
        if value is not None:
            out[key] = colour(value)
    glossiness = getattr(material, "glossiness", None)
    if glossiness is not None:
        out["Ns"] = float(glossiness)
    out["map_Kd"] = image(getattr(material, "image", None))
    return out

"""Scenes from arrays: the same image as the scene files that spell the same meshes,
materials, lights and environment (transforms: the flattened file with every copy
written out); bad arrays are ValueErrors naming the argument and the first bad element;
a trimesh object renders as the OBJ file it came from."""

import warnings

import numpy as np
import pytest

import raytracer

VIEW = dict(width=32, height=24, look_from=(0.3, 0.4, 4.0), look_to=(0.0, 0.0, 0.0), fov=50)

QUAD = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float64)
QUAD_FACES = np.array([[0, 1, 2], [0, 2, 3]])
QUAD_UVS = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float64)
QUAD_NORMALS = np.array([[0.2, 0, 1], [0, 0.2, 1], [-0.2, 0, 1], [0, -0.2, 1]])
#: Values 8-bit colours hold exactly (k / 255), as trimesh keeps them.
MTL = "newmtl a\nKa 0.2 0.2 0.2\nKd 1 0.8 0.6\nKs 0.4 0.4 0.4\nNs 20\nmap_Kd tex.png\n"
MATERIAL = {"Ka": [0.2, 0.2, 0.2], "Kd": [1, 0.8, 0.6], "Ks": [0.4, 0.4, 0.4], "Ns": 20}
TEXTURE = (np.arange(4 * 4 * 3).reshape(4, 4, 3) * 5 % 256).astype(np.uint8)


def obj_text(copies, normals=True) -> str:
    lines = ["mtllib m.mtl", "usemtl a"]
    for offset in copies:
        lines += [f"v {x + offset[0]} {y + offset[1]} {z + offset[2]}" for x, y, z in QUAD]
    lines += [f"vt {u} {v}" for u, v in QUAD_UVS]
    if normals:
        lines += [f"vn {x} {y} {z}" for x, y, z in QUAD_NORMALS]
    for c in range(len(copies)):
        for face in QUAD_FACES:
            corners = [f"{c * 4 + i + 1}/{i + 1}" + (f"/{i + 1}" if normals else "") for i in face]
            lines.append("f " + " ".join(corners))
    return "\n".join(lines) + "\n"


@pytest.fixture
def files(tmp_path):
    raytracer.write_png(TEXTURE, tmp_path / "tex.png")
    (tmp_path / "m.mtl").write_text(MTL)
    return tmp_path


def test_arrays_render_as_the_flattened_scene_file(files):
    copies = [(0.0, 0.0, 0.0), (0.5, 0.25, -1.0)]
    (files / "q.obj").write_text(obj_text(copies))
    light = {"type": "point", "position": [0.0, 1.0, 3.0], "intensity": [4.0, 4.0, 4.0]}
    (files / "s.toml").write_text(
        '[[mesh]]\nfile = "q.obj"\n\n[[light]]\ntype = "point"\nposition = [0.0, 1.0, 3.0]\nintensity = [4.0, 4.0, 4.0]\n'
    )
    transforms = np.stack([np.eye(4), np.eye(4)])
    transforms[1, :3, 3] = copies[1]
    for texture in (TEXTURE, files / "tex.png"):
        scene = raytracer.Scene.from_arrays(
            meshes=[
                dict(
                    vertices=QUAD,
                    faces=QUAD_FACES,
                    normals=QUAD_NORMALS,
                    uvs=QUAD_UVS,
                    material={**MATERIAL, "map_Kd": texture},
                    transforms=transforms,
                )
            ],
            lights=[light],
        )
        for mode, spp in (("full", 1), ("path", 2), ("depth", 1)):
            expected = raytracer.render(files / "s.toml", mode=mode, spp=spp, **VIEW)
            assert np.array_equal(scene.render(mode=mode, spp=spp, **VIEW), expected), (mode, type(texture))
        # The copies are instances of the one mesh stored once.
        assert scene.counts == dict(triangles=2, placed_triangles=4, meshes=1, instances=2, primitives=2)
        assert scene.object_names == ["meshes[0] copy 0", "meshes[0] copy 1"]


def test_the_environment_and_a_plain_mesh(tmp_path):
    sky = (np.random.default_rng(1).random((8, 16, 3)) * 2).astype(np.float32)
    raytracer.write_image(sky, tmp_path / "sky.exr")
    (tmp_path / "q.obj").write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n")
    expected = raytracer.render(tmp_path / "q.obj", mode="path", spp=2, env=tmp_path / "sky.exr", env_rotation=40, **VIEW)
    for file in (sky, tmp_path / "sky.exr"):
        scene = raytracer.Scene.from_arrays(
            meshes=[dict(vertices=QUAD, faces=QUAD_FACES)], environment={"file": file, "rotation": 40}
        )
        assert np.array_equal(scene.render(mode="path", spp=2, **VIEW), expected)


@pytest.mark.parametrize(
    "mesh,message",
    [
        (dict(vertices=QUAD[:, :2], faces=QUAD_FACES), r"meshes\[0\]\['vertices'\] must have the shape \(n, 3\)"),
        (dict(vertices=QUAD.astype(str), faces=QUAD_FACES), r"meshes\[0\]\['vertices'\] must be an \(n, 3\) array of numbers"),
        (dict(vertices=np.where(np.arange(12).reshape(4, 3) == 7, np.nan, QUAD), faces=QUAD_FACES),
         r"meshes\[0\]\['vertices'\]\[2\] is \[1.0, nan, 0.0\]: not finite"),
        (dict(vertices=QUAD, faces=QUAD_FACES.astype(float)), r"meshes\[0\]\['faces'\] must be an \(m, 3\) array of integers"),
        (dict(vertices=QUAD, faces=[[0, 1, 2], [0, 2, 4]]), r"meshes\[0\]\['faces'\]\[1\] is \[0, 2, 4\]: vertex indices must be in 0..4"),
        (dict(vertices=QUAD, faces=[[0, 1, -1]]), r"meshes\[0\]\['faces'\]\[0\] is \[0, 1, -1\]"),
        (dict(vertices=QUAD, faces=QUAD_FACES, normals=QUAD_NORMALS[:3]), r"meshes\[0\]\['normals'\] has 3 rows"),
        (dict(vertices=QUAD, faces=QUAD_FACES, uvs=QUAD_UVS * np.inf), r"meshes\[0\]\['uvs'\]\[0\] .* not finite"),
        (dict(vertices=QUAD, faces=QUAD_FACES, transforms=np.zeros((4, 4)) + np.eye(4)[3:] * 0 + np.diag([1, 1, 0, 1])),
         r"meshes\[0\]\['transforms'\]\[0\] is singular"),
        (dict(vertices=QUAD, faces=QUAD_FACES, transforms=np.zeros((0, 4, 4))), r"meshes\[0\]\['transforms'\] holds no matrix"),
        (dict(vertices=QUAD, faces=QUAD_FACES, transforms=[np.eye(4), np.eye(4) + np.eye(4, k=3) * 1e39]),
         r"meshes\[0\]\['transforms'\]\[1\]: non-finite value 1e39"),
        (dict(vertices=QUAD, faces=QUAD_FACES, material={"Kx": 1}), r"materials.meshes\[0\].Kx: unknown field"),
        (dict(vertices=QUAD, faces=QUAD_FACES, colour=1), r"meshes\[0\]: unknown key 'colour'"),
        (dict(vertices=QUAD, faces=QUAD_FACES, colors=np.ones((3, 3))), r"meshes\[0\]\['colors'\] has 3 rows"),
    ],
)
def test_bad_arrays_are_value_errors_naming_the_first_bad_element(mesh, message):
    with pytest.raises(ValueError, match=message):
        raytracer.Scene.from_arrays(meshes=[{"vertices": QUAD, "faces": QUAD_FACES}, mesh][1:])


def test_vertex_colors_render_as_the_obj_that_spells_them(tmp_path):
    colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]], dtype=np.uint8) * 255
    lines = [f"v {x} {y} {z} {r / 255} {g / 255} {b / 255}" for (x, y, z), (r, g, b) in zip(QUAD, colors)]
    (tmp_path / "q.obj").write_text("\n".join(lines) + "\nf 1 2 3\nf 1 3 4\n")
    expected = raytracer.render(tmp_path / "q.obj", **VIEW)
    for given in (colors, colors / 255.0, np.hstack([colors / 255.0, np.ones((4, 1))])):
        scene = raytracer.Scene.from_arrays(meshes=[dict(vertices=QUAD, faces=QUAD_FACES, colors=given)])
        assert np.array_equal(scene.render(**VIEW), expected), given.dtype
    plain = raytracer.Scene.from_arrays(meshes=[dict(vertices=QUAD, faces=QUAD_FACES)])
    assert not np.array_equal(plain.render(**VIEW), expected)


def test_a_trimesh_renders_as_the_obj_it_came_from(files):
    trimesh = pytest.importorskip("trimesh")
    for normals in (False, True):
        (files / "q.obj").write_text(obj_text([(0.0, 0.0, 0.0)], normals=normals))
        expected = raytracer.render(files / "q.obj", **VIEW)
        for loaded in (trimesh.load(files / "q.obj", process=False), trimesh.load(files / "q.obj", process=False, force="scene")):
            scene = raytracer.Scene.from_trimesh(loaded)
            assert np.array_equal(scene.render(**VIEW), expected), (normals, type(loaded))
    with pytest.raises(ValueError, match="trimesh.Trimesh or trimesh.Scene"):
        raytracer.Scene.from_trimesh(42)


def test_a_trimesh_with_vertex_colors_renders_as_the_ply_it_came_from(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    colors = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 0]])
    header = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
    header += "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    header += "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
    vertices = [f"{x} {y} {z} {r} {g} {b}" for (x, y, z), (r, g, b) in zip(QUAD, colors)]
    faces = [f"3 {a} {b} {c}" for a, b, c in QUAD_FACES]
    (tmp_path / "q.ply").write_text(header + "\n".join(vertices + faces) + "\n")
    expected = raytracer.render(tmp_path / "q.ply", **VIEW)
    loaded = trimesh.load(tmp_path / "q.ply", process=False)
    assert loaded.visual.kind == "vertex"
    assert np.array_equal(raytracer.Scene.from_trimesh(loaded).render(**VIEW), expected)
    plain = raytracer.Scene.from_arrays(meshes=[dict(vertices=QUAD, faces=QUAD_FACES)])
    assert not np.array_equal(plain.render(**VIEW), expected)


def test_aovs_depth_and_object_ids_are_the_analytic_ones():
    """Two quads on the plane z = 0 seen by an intrinsics camera at z = D looking down
    -Z: the z-depth is D wherever they are, inf elsewhere, and each object id covers
    exactly the pixels whose centres project inside its quad."""
    width, height, D = 40, 30, 4.0
    fx, fy, cx, cy = 30.0, 30.0, (width - 1) / 2, (height - 1) / 2
    boxes = [(-2.02, -0.51, -1.03, 1.22), (0.33, 2.07, -0.71, 0.49)]  # x0, x1, y0, y1: no pixel centre on an edge
    meshes = [
        dict(vertices=[[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], faces=[[0, 1, 2], [0, 2, 3]], name=f"box{k}")
        for k, (x0, x1, y0, y1) in enumerate(boxes)
    ]
    scene = raytracer.Scene.from_arrays(meshes=meshes)
    assert scene.object_names == ["box0", "box1"]
    pose = np.eye(4)
    pose[2, 3] = D
    out = scene.render(
        camera_to_world=pose, intrinsics=(fx, fy, cx, cy), width=width, height=height, spp=4,
        aovs=["depth", "object_id", "alpha", "normal", "material_id"],
    )
    assert set(out) == {"color", "depth", "object_id", "alpha", "normal", "material_id"}
    assert out["object_id"].dtype == np.int32 and out["depth"].shape == (height, width)
    u, v = np.meshgrid(np.arange(width), np.arange(height))
    x, y = D * (u - cx) / fx, -D * (v - cy) / fy  # OpenCV's y is down; the world's +Y up
    expected = np.full((height, width), -1)
    for k, (x0, x1, y0, y1) in enumerate(boxes):
        expected[(x > x0) & (x < x1) & (y > y0) & (y < y1)] = k
    assert np.array_equal(out["object_id"], expected)
    hit = expected >= 0
    assert np.isinf(out["depth"][out["alpha"] == 0]).all() and (out["alpha"][~hit] < 1).all()
    # Pixels wholly inside a quad (every sample hits): z-depth D, normal +Z, alpha 1.
    inside = hit & (np.abs(out["alpha"] - 1) == 0)
    assert inside.sum() > 100
    assert np.abs(out["depth"][inside] - D).max() < 1e-5
    assert np.abs(out["normal"][inside] - [0, 0, 1]).max() < 1e-6
    assert (out["material_id"][hit] >= 0).all() and (out["material_id"][~hit] == -1).all()
    with pytest.raises(ValueError, match='invalid aovs: unknown output "colour"'):
        scene.render(width=4, height=3, aovs=["colour"])


def _placed(matrix, points, normals=None):
    """``points`` (and ``normals``, by the inverse transpose) moved by ``matrix``: the
    copy a flattened scene would hold."""
    moved = points @ matrix[:3, :3].T + matrix[:3, 3]
    return moved if normals is None else (moved, normals @ np.linalg.inv(matrix[:3, :3]))


def test_copies_are_instances_that_render_as_the_flattened_copies():
    """A mesh placed three times (turned, stretched, mirrored) is stored once and
    renders as three meshes whose vertices numpy moved (a one-level scene), up to the
    rounding of the placement (rays moved into the mesh's space against corners moved
    into the world's): as the TOML reader's instances, at most 0.1% of the pixels
    differ, by at most 2/255."""
    c, s = np.cos(0.6), np.sin(0.6)
    turn = np.array([[c, 0, s, -1.3], [0, 1, 0, 0.2], [-s, 0, c, -0.4], [0, 0, 0, 1]])
    stretch = np.diag([0.6, 1.4, 1.0, 1.0])
    stretch[:3, 3] = [1.2, -0.3, -1.0]
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0]) @ turn
    transforms = np.stack([turn, stretch, mirror])
    light = {"type": "point", "position": [0.5, 2.0, 4.0], "intensity": [6.0, 6.0, 6.0]}
    mesh = dict(vertices=QUAD, faces=QUAD_FACES, normals=QUAD_NORMALS, uvs=QUAD_UVS,
                material={**MATERIAL, "map_Kd": TEXTURE})
    instanced = raytracer.Scene.from_arrays(meshes=[{**mesh, "transforms": transforms}], lights=[light])
    copies = []
    for m in transforms:
        vertices, normals = _placed(m, QUAD, QUAD_NORMALS)
        copies.append({**mesh, "vertices": vertices, "normals": normals})
    flat = raytracer.Scene.from_arrays(meshes=copies, lights=[light])
    assert instanced.counts == dict(triangles=2, placed_triangles=6, meshes=1, instances=3, primitives=2)
    assert flat.counts == dict(triangles=6, placed_triangles=6, meshes=0, instances=0, primitives=6)
    view = dict(VIEW, width=96, height=72)
    for mode, spp in (("full", 1), ("path", 4), ("normal", 1)):
        a = raytracer.postprocess(instanced.render(mode=mode, spp=spp, **view), mode)
        b = raytracer.postprocess(flat.render(mode=mode, spp=spp, **view), mode)
        differ = np.abs(a.astype(int) - b.astype(int)).max(axis=2)
        assert (differ > 0).sum() * 1000 <= differ.size and differ.max() <= 2, (mode, (differ > 0).sum(), differ.max())
        assert a.max() > 0
    ids = [s.render(aovs=["object_id"], **view)["object_id"] for s in (instanced, flat)]
    assert set(np.unique(ids[0])) == {-1, 0, 1, 2}
    assert (ids[0] != ids[1]).sum() * 1000 <= ids[0].size


def test_a_thousand_copies_of_a_large_mesh_are_stored_once():
    """1,000 transforms of a 10,000-triangle grid: the scene stores 10,000 triangles
    (flattened, it would be 10 million), and renders the copies."""
    n = 50  # (n x 2n) quads of two triangles
    x, y = np.meshgrid(np.linspace(0, 1, 2 * n + 1), np.linspace(0, 1, n + 1))
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    corner = (np.arange(n)[:, None] * (2 * n + 1) + np.arange(2 * n)[None, :]).ravel()
    row = 2 * n + 1
    faces = np.concatenate([np.stack([corner, corner + 1, corner + row + 1], 1), np.stack([corner, corner + row + 1, corner + row], 1)])
    assert len(faces) == 10_000
    transforms = np.tile(np.eye(4), (1000, 1, 1))
    transforms[:, 0, 3] = np.arange(1000) % 40 * 1.1
    transforms[:, 1, 3] = np.arange(1000) // 40 * 1.1
    with warnings.catch_warnings():
        # Not "no shapes left to render": the scene's one level holds none of its own.
        warnings.simplefilter("error", raytracer.RaytracerWarning)
        scene = raytracer.Scene.from_arrays(meshes=[dict(vertices=vertices, faces=faces, transforms=transforms, name="grid")])
    assert scene.counts == dict(triangles=10_000, placed_triangles=10_000_000, meshes=1, instances=1000, primitives=10_000)
    assert len(scene.object_names) == 1000 and scene.object_names[999] == "grid copy 999"
    ids = scene.render(width=40, height=25, look_from=(22, 13.7, 14), look_to=(22, 13.7, 0), aovs=["object_id"])["object_id"]
    assert len(np.unique(ids)) > 500

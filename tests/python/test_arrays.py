"""Scenes from arrays: the same image as the scene files that spell the same meshes,
materials, lights and environment (transforms: the flattened file with every copy
written out); bad arrays are ValueErrors naming the argument and the first bad element;
a trimesh object renders as the OBJ file it came from."""

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

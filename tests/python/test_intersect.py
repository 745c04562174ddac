"""`Scene.intersect` and `Scene.occluded`: the closest hit of each of an array of rays,
its primitive numbered as the file lists it, and whether anything blocks it, checked
against a brute-force test of every triangle."""

import numpy as np
import pytest

import raytracer


def write_obj(path, triangles, extra=""):
    """An OBJ file of `triangles` (an (n, 3, 3) array), in that order."""
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in triangles.reshape(-1, 3)]
    lines += [f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}" for i in range(len(triangles))]
    path.write_text("\n".join(lines) + "\n" + extra)
    return path


def brute_force(triangles, origins, directions):
    """Distance, triangle and barycentrics of every ray's nearest hit (Moller-Trumbore
    in float64 over every triangle), the second-nearest distance, how far inside its
    triangle's edges the hit is, and how far inside any triangle ahead the ray comes
    (negative: outside all): rays whose answer rounding may change are told apart by
    the last three."""
    d = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    a, b, c = (triangles[:, k].astype(np.float64) for k in range(3))
    e1, e2 = b - a, c - a
    p = np.cross(d[:, None, :], e2[None])
    det = np.einsum("rtk,tk->rt", p, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = origins[:, None, :] - a[None]
        u = np.einsum("rtk,rtk->rt", s, p) * inv
        q = np.cross(s, e1[None])
        v = np.einsum("rk,rtk->rt", d, q) * inv
        t = np.einsum("tk,rtk->rt", e2, q) * inv
    ahead = (np.abs(det) > 1e-12) & (t > 1e-4)
    inside = np.where(ahead, np.minimum(np.minimum(u, v), 1 - u - v), -np.inf)
    hit = ahead & (inside >= 0)
    t = np.where(hit, t, np.inf)
    order = np.argsort(t, axis=1)
    rows = np.arange(len(origins))
    nearest, second = order[:, 0], order[:, 1]
    t_near = t[rows, nearest]
    u_near, v_near = u[rows, nearest], v[rows, nearest]
    edge = np.minimum(np.minimum(u_near, v_near), 1 - u_near - v_near)
    return t_near, nearest, u_near, v_near, t[rows, second], edge, inside.max(axis=1)


def test_hits_are_those_of_every_triangle_tested(tmp_path):
    rng = np.random.default_rng(7)
    corners = rng.uniform(-1, 1, size=(400, 1, 3))
    triangles = (corners + rng.normal(scale=0.25, size=(400, 3, 3))).astype(np.float32)
    path = write_obj(tmp_path / "soup.obj", triangles)
    scene = raytracer.Scene(path)
    origins = rng.uniform(-2, 2, size=(3000, 3)).astype(np.float32)
    targets = rng.uniform(-2, 2, size=(3000, 3))
    directions = (targets - origins) * rng.uniform(0.1, 10, size=(3000, 1))

    hits = scene.intersect(origins, directions)
    assert set(hits) == {"t", "primitive", "u", "v"}
    assert hits["t"].dtype == np.float32 and hits["primitive"].dtype == np.int64
    assert all(a.shape == (3000,) for a in hits.values())

    t, nearest, u, v, t_second, edge, closest_call = brute_force(triangles, origins.astype(np.float64), directions)
    missed = ~np.isfinite(t)
    # Rays whose nearest hit is clear of its edges and of the next hit: the answer
    # cannot depend on rounding.
    with np.errstate(invalid="ignore"):  # inf - inf where no triangle is hit
        clear = ~missed & (edge > 1e-4) & (t_second - t > 1e-3 * t)
    clear_miss = missed & (closest_call < -1e-4)
    assert clear.sum() > 1500 and clear_miss.sum() > 1000, "too few rays of either kind"
    assert np.array_equal(hits["primitive"][clear], nearest[clear])
    np.testing.assert_allclose(hits["t"][clear], t[clear], rtol=1e-4)
    np.testing.assert_allclose(hits["u"][clear], u[clear], atol=1e-4)
    np.testing.assert_allclose(hits["v"][clear], v[clear], atol=1e-4)
    assert np.all(hits["primitive"][clear_miss] == -1)
    assert np.all(np.isinf(hits["t"][clear_miss]))
    # Every hit's barycentrics and distance name the same point.
    found = hits["primitive"] >= 0
    a, b, c = (triangles[hits["primitive"][found], k] for k in range(3))
    uu, vv = hits["u"][found, None], hits["v"][found, None]
    on_triangle = (1 - uu - vv) * a + uu * b + vv * c
    unit = directions[found] / np.linalg.norm(directions[found], axis=1, keepdims=True)
    along_ray = origins[found] + hits["t"][found, None] * unit
    np.testing.assert_allclose(on_triangle, along_ray, atol=1e-4)


def test_occlusion_is_that_of_every_triangle_tested(tmp_path):
    rng = np.random.default_rng(8)
    corners = rng.uniform(-1, 1, size=(300, 1, 3))
    triangles = (corners + rng.normal(scale=0.25, size=(300, 3, 3))).astype(np.float32)
    scene = raytracer.Scene(write_obj(tmp_path / "soup.obj", triangles))
    origins = rng.uniform(-2, 2, size=(3000, 3)).astype(np.float32)
    directions = rng.uniform(-2, 2, size=(3000, 3)) - origins
    t_max = rng.uniform(0, 4, size=3000).astype(np.float32)

    blocked = scene.occluded(origins, directions, t_max)
    assert blocked.dtype == np.bool_ and blocked.shape == (3000,)
    t, _, _, _, _, edge, closest_call = brute_force(triangles, origins.astype(np.float64), directions)
    # Rays whose answer cannot depend on rounding: a hit clear of its edges and of
    # the reach, or no triangle anywhere near.
    hit_clear = np.isfinite(t) & (edge > 1e-4) & (np.abs(t - t_max) > 1e-3 * t_max)
    miss_clear = ~np.isfinite(t) & (closest_call < -1e-4)
    assert hit_clear.sum() > 1000 and (hit_clear & (t < t_max)).sum() > 300
    assert np.array_equal(blocked[hit_clear], t[hit_clear] < t_max[hit_clear])
    assert not blocked[miss_clear].any()
    # One reach for all, none, and the closest hits' own distances agree.
    hits = scene.intersect(origins, directions)
    assert np.array_equal(scene.occluded(origins, directions), hits["primitive"] >= 0)
    assert np.array_equal(scene.occluded(origins, directions, 1.5), hits["t"] < 1.5)
    assert np.array_equal(scene.occluded(origins, directions, t_max.astype(np.float64)), blocked)


def test_primitives_are_numbered_as_the_file_lists_them(tmp_path):
    # A pentagon (three triangles fanned from its first corner), a zero-area triangle
    # (skipped, but numbered), a triangle, then a sphere: numbers 0-2, 4 and 5.
    (tmp_path / "shapes.obj").write_text(
        "v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 2 0\nv -1 1 0\n"
        "v 5 0 0\nv 6 0 0\nv 7 0 0\n"
        "v 10 0 0\nv 12 0 0\nv 10 2 0\n"
        "f 1 2 3 4 5\nf 6 7 8\nf 9 10 11\nS 20 0 0 1\n"
    )
    scene = raytracer.Scene(tmp_path / "shapes.obj")
    fan = np.array([[0, 0, 0], [2, 0, 0], [3, 1, 0], [1, 2, 0], [-1, 1, 0]], np.float64)
    centroids = [(fan[0] + fan[k] + fan[k + 1]) / 3 for k in (1, 2, 3)]
    centroids += [np.array([10.5, 0.5, 0]), np.array([20, 0, 0])]
    origins = np.array(centroids) + [0, 0, 5]
    hits = scene.intersect(origins, [[0, 0, -1]] * 5)
    assert hits["primitive"].tolist() == [0, 1, 2, 4, 5]
    np.testing.assert_allclose(hits["t"], [5, 5, 5, 5, 4], rtol=1e-6)
    assert hits["u"][4] == 0 and hits["v"][4] == 0


def test_rays_pass_through_what_a_material_cuts_out(tmp_path):
    # A square (triangles 0 and 1) whose map_d is black on its left half, in front of
    # a plain triangle (2): rays through the left half reach the triangle behind.
    rgb = np.zeros((4, 8, 3), np.uint8)
    rgb[:, 4:] = 255
    raytracer.write_png(rgb, tmp_path / "half.png")
    (tmp_path / "cut.mtl").write_text("newmtl cut\nKd 1 1 1\nmap_d half.png\nnewmtl plain\nKd 1 1 1\n")
    (tmp_path / "cut.obj").write_text(
        "mtllib cut.mtl\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "v -1 -1 -1\nv 2 -1 -1\nv 0.5 2 -1\n"
        "usemtl cut\nf 1/1 2/2 3/3 4/4\nusemtl plain\nf 5 6 7\n"
    )
    scene = raytracer.Scene(tmp_path / "cut.obj")
    origins, directions = [[0.2, 0.5, 1], [0.8, 0.5, 1]], [[0, 0, -1]] * 2
    hits = scene.intersect(origins, directions)
    assert hits["primitive"].tolist()[0] == 2 and hits["primitive"][1] in (0, 1)
    np.testing.assert_allclose(hits["t"], [2, 1], rtol=1e-6)
    assert scene.occluded(origins, directions, 1.5).tolist() == [False, True]


def test_rays_come_as_lists_or_arrays_of_any_float_type(tmp_path):
    triangles = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32)
    scene = raytracer.Scene(write_obj(tmp_path / "one.obj", triangles))
    expected = scene.intersect(np.array([[0.2, 0.2, 1]], np.float32), np.array([[0, 0, -2]], np.float32))
    for origins, directions in [
        ([[0.2, 0.2, 1]], [[0, 0, -2]]),
        (np.array([[0.2, 0.2, 1]]), np.array([[0, 0, -2]], np.float64)),
    ]:
        hits = scene.intersect(origins, directions)
        assert {k: v.tolist() for k, v in hits.items()} == {k: v.tolist() for k, v in expected.items()}
    assert expected["primitive"].tolist() == [0] and expected["t"].tolist() == [1.0]
    # Directions too short or too long to square in float32 still point somewhere.
    for length in (1e-30, 1e-44, 1e30, 3e38):
        hits = scene.intersect(np.array([[0.2, 0.2, 1]], np.float32), np.array([[0, 0, -length]], np.float32))
        assert hits["primitive"].tolist() == [0] and hits["t"].tolist() == [1.0], length
    empty = scene.intersect(np.zeros((0, 3)), np.zeros((0, 3)))
    assert all(a.shape == (0,) for a in empty.values())


@pytest.mark.parametrize(
    "origins,directions,message",
    [
        ([[0, 0, 1, 0]], [[0, 0, -1, 0]], r"origins must have the shape \(n, 3\), .* not \(1, 4\)"),
        ([[0, 0, 1]], [[0, 0]], r"directions must have the shape \(n, 3\), .* not \(1, 2\)"),
        ([0, 0, 1], [0, 0, -1], r"origins must have the shape \(n, 3\), .* not \(3,\)"),
        ([[0, 0, 1]], np.zeros((1, 3, 1)), r"directions must have .* not \(1, 3, 1\)"),
        ([[0, "x", 1]], [[0, 0, -1]], "origins must be an \\(n, 3\\) array of numbers: .*'x'"),
        ([[0, 0, 1]] * 2, [[0, 0, -1]], "2 origins but 1 directions"),
        ([[0, 0, 1], [0, float("nan"), 1]], [[0, 0, -1]] * 2, "ray 1: .* must be finite"),
        ([[0, 0, 1]], [[0, 0, float("inf")]], "ray 0: .* must be finite"),
        ([[0, 0, 1]] * 3, [[0, 0, -1], [0, 0, -1], [0, 0, 0]], "ray 2: the direction .* is zero"),
    ],
)
def test_bad_rays_are_named(tmp_path, origins, directions, message):
    triangles = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32)
    scene = raytracer.Scene(write_obj(tmp_path / "one.obj", triangles))
    with pytest.raises(ValueError, match=message):
        scene.intersect(origins, directions)


@pytest.mark.parametrize(
    "t_max,message",
    [
        ([1.0, 2.0], r"t_max must be one number or one per ray \(3\), not \(2,\)"),
        ([[1.0, 2.0, 3.0]], r"t_max must be one number or one per ray \(3\), not \(1, 3\)"),
        ([1.0, float("nan"), 3.0], "ray 1: t_max is NaN"),
        (float("nan"), "t_max is NaN"),
        ("far", "t_max must be a number or an array of numbers: .*'far'"),
    ],
)
def test_bad_reaches_are_named(tmp_path, t_max, message):
    triangles = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32)
    scene = raytracer.Scene(write_obj(tmp_path / "one.obj", triangles))
    with pytest.raises(ValueError, match=message):
        scene.occluded([[0.2, 0.2, 1]] * 3, [[0, 0, -1]] * 3, t_max)


def test_the_first_bad_ray_is_named(tmp_path):
    # Rays are checked a chunk at a time on all cores: the error must still name the
    # first bad row, whichever chunk is checked first.
    triangles = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32)
    scene = raytracer.Scene(write_obj(tmp_path / "one.obj", triangles))
    origins = np.tile([0.2, 0.2, 1.0], (5000, 1))
    directions = np.tile([0.0, 0.0, -1.0], (5000, 1))
    origins[4321, 1] = np.nan
    directions[3000] = 0
    directions[1234] = 0
    with pytest.raises(ValueError, match="ray 1234: the direction"):
        scene.intersect(origins, directions)
    with pytest.raises(ValueError, match="ray 1234: the direction"):
        scene.occluded(origins, directions)
    directions[:] = [0, 0, -1]
    with pytest.raises(ValueError, match="ray 4321: .* must be finite"):
        scene.intersect(origins, directions)
    # Views that are not contiguous (rows reversed, every other row of a column slice)
    # are read as the rows they show.
    wide = np.zeros((10000, 5), np.float32)
    wide[1::2, 1:4] = directions * np.arange(1, 5001)[:, None]
    origins = np.tile(np.float32([0.2, 0.2, 1.0]), (5000, 1))
    origins[:, 2] += np.arange(5000, dtype=np.float32) / 1000
    hits = scene.intersect(origins[::-1], wide[1::2, 1:4])
    assert np.all(hits["primitive"] == 0)
    np.testing.assert_allclose(hits["t"], origins[::-1, 2], rtol=1e-6)


def test_a_mesh_from_arrays_is_the_mesh_of_its_file(tmp_path):
    rng = np.random.default_rng(9)
    vertices = rng.uniform(-1, 1, size=(60, 3)).astype(np.float32)
    faces = rng.integers(0, 60, size=(80, 3))
    faces[5] = [3, 3, 4]  # zero area: skipped, and still numbered
    from_arrays = raytracer.Scene.from_mesh(vertices, faces.astype(np.int32))
    path = write_obj(tmp_path / "mesh.obj", vertices[faces])
    from_file = raytracer.Scene(path)
    assert from_arrays.path is None and "a mesh" in repr(from_arrays)
    assert any("degenerate" in w for w in from_arrays.warnings)
    origins = rng.uniform(-2, 2, size=(2000, 3)).astype(np.float32)
    directions = rng.uniform(-1, 1, size=(2000, 3)).astype(np.float32) - origins
    mine, theirs = from_arrays.intersect(origins, directions), from_file.intersect(origins, directions)
    assert (mine["primitive"] >= 0).sum() > 500
    for key in ("t", "primitive", "u", "v"):
        assert np.array_equal(mine[key], theirs[key]), key
    # Rendered with the default camera and lights, as the command line renders the file.
    options = dict(width=24, height=16)
    assert np.array_equal(from_arrays.render(**options), from_file.render(**options))


@pytest.mark.parametrize(
    "vertices,faces,message",
    [
        ([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], r"vertices must have the shape \(n, 3\), .* not \(3, 2\)"),
        ([[0, 0, 0], [1, float("nan"), 0], [0, 1, 0]], [[0, 1, 2]], "vertex 1: .* is not finite"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2], [0, 1, 3]], r"face 1: vertex index 3 is not in 0\.\.3"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, -1, 2]], r"face 0: vertex index -1 is not in 0\.\.3"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1.5, 2]], "faces must be an .* array of integers .*: not float64"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [0, 1, 2], r"faces must have the shape \(m, 3\), .* not \(3,\)"),
    ],
)
def test_bad_meshes_are_named(vertices, faces, message):
    with pytest.raises(ValueError, match=message):
        raytracer.Scene.from_mesh(vertices, faces)

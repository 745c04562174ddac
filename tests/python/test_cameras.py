"""Cameras from poses and intrinsics: a 4x4 camera-to-world matrix (OpenGL's
convention) is the look-at camera of the same pose in every mode, bit for bit when the
pose is exact; OpenCV intrinsics put known points at their pixel centres; TOML's
`[camera] matrix` and `intrinsics` are the same cameras; bad matrices are refused by
name."""

import numpy as np
import pytest

import raytracer
from raytracer.cameras import camera_to_world_from_opencv, opencv_from_camera_to_world
from conftest import CORNELL_OBJ

MODES = [("full", 1), ("depth", 1), ("normal", 1), ("path", 2)]

#: Quarter turns about +Y, with the look-at camera of the same pose: the camera at
#: `position` looking along `ahead`.
QUARTER_TURNS = [
    # No turn: looking down -Z.
    ([[1, 0, 0], [0, 1, 0], [0, 0, 1]], (0.0, 0.7, 1.75), (0.0, 0.7, 0.0)),
    # +90 degrees about +Y: -Z turns to -X; right is -Z, backward +X.
    ([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], (1.75, 0.7, 0.0), (0.0, 0.7, 0.0)),
    # 180 degrees: looking down +Z from inside the box's back.
    ([[-1, 0, 0], [0, 1, 0], [0, 0, -1]], (0.0, 0.7, -0.5), (0.0, 0.7, 1.0)),
]


def pose(rotation, position) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3] = rotation
    matrix[:3, 3] = position
    return matrix


@pytest.mark.parametrize("mode,spp", MODES)
def test_an_exact_pose_is_the_look_at_camera_bit_for_bit(mode, spp):
    scene = raytracer.Scene(CORNELL_OBJ)
    for rotation, position, target in QUARTER_TURNS:
        common = dict(width=24, height=18, fov=60, mode=mode, spp=spp)
        by_matrix = scene.render(camera_to_world=pose(rotation, position), **common)
        by_look_at = scene.render(look_from=position, look_to=target, **common)
        assert np.array_equal(by_matrix.view(np.uint32), by_look_at.view(np.uint32)), (mode, position)
    # And the pose matters: another turn is another image.
    turned = scene.render(camera_to_world=pose(QUARTER_TURNS[1][0], QUARTER_TURNS[0][1]), **common)
    assert not np.array_equal(turned, by_look_at)


def test_a_general_pose_agrees_with_the_look_at_camera():
    """A rotation that is not exact in floating point: the same rays to rounding."""
    scene = raytracer.Scene(CORNELL_OBJ)
    angle = np.radians(20.0)
    rotation = [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]]
    position = np.array([0.6, 0.7, 1.6])
    target = position - np.array(rotation)[:, 2]
    by_matrix = scene.camera_rays(camera_to_world=pose(rotation, position), width=16, height=12, fov=50)
    by_look_at = scene.camera_rays(look_from=position, look_to=target, width=16, height=12, fov=50)
    assert np.abs(by_matrix["directions"] - by_look_at["directions"]).max() < 1e-6
    assert np.array_equal(by_matrix["origins"], by_look_at["origins"])


def test_intrinsics_reproject_known_points_to_their_pixel_centres():
    """Points placed by OpenCV's model on the pixel centres of an intrinsics camera
    lie on the renderer's camera rays through those pixels, within 0.01 px."""
    width, height = 64, 48
    fx, fy, cx, cy = 70.0, 55.0, 30.25, 25.5  # off-centre, non-square pixels
    rng = np.random.default_rng(7)
    rotation = camera_to_world_from_opencv(rng.normal(size=3) * 0.5, [0.1, -0.2, 3.0])[:3, :3]
    r_cv, t_cv = opencv_from_camera_to_world(pose(rotation, [0.3, 0.2, 2.0]))
    camera_to_world = camera_to_world_from_opencv(r_cv, t_cv)
    scene = raytracer.Scene(CORNELL_OBJ)
    rays = scene.camera_rays(camera_to_world=camera_to_world, intrinsics=(fx, fy, cx, cy), width=width, height=height)
    for u, v, depth in [(0, 0, 1.0), (63, 47, 2.5), (30, 25, 0.7), (5, 40, 4.0), (50, 3, 1.5)]:
        # OpenCV: the camera-space point at this depth seen at pixel (u, v).
        camera_point = depth * np.array([(u - cx) / fx, (v - cy) / fy, 1.0])
        world = r_cv.T @ (camera_point - t_cv)
        # Its projection by OpenCV's formula is (u, v) again...
        x, y, z = r_cv @ world + t_cv
        assert abs(fx * x / z + cx - u) < 1e-9 and abs(fy * y / z + cy - v) < 1e-9
        # ...and the renderer's ray through pixel (u, v) passes through it.
        origin = rays["origins"][v, u].astype(np.float64)
        direction = rays["directions"][v, u].astype(np.float64)
        offset = world - origin
        miss = offset - direction * (offset @ direction)
        # Off the ray by `miss`: that many pixels at this depth.
        error_px = np.linalg.norm(miss) / depth * max(fx, fy)
        assert error_px < 0.01, (u, v, error_px)


def test_intrinsics_of_the_fov_are_the_fov_camera():
    width, height, fov = 40, 30, 60.0
    f = (height / 2) / np.tan(np.radians(fov) / 2)
    scene = raytracer.Scene(CORNELL_OBJ)
    common = dict(width=width, height=height, look_from=(0, 0.7, 1.75), look_to=(0, 0.7, 0))
    a = scene.camera_rays(fov=fov, **common)["directions"]
    b = scene.camera_rays(intrinsics=(f, f, (width - 1) / 2, (height - 1) / 2), **common)["directions"]
    assert np.abs(a - b).max() < 1e-6
    image = scene.render(intrinsics=(f, f, (width - 1) / 2, (height - 1) / 2), mode="depth", **common)
    assert np.abs(image - scene.render(fov=fov, mode="depth", **common)).max() < 1e-4


def test_the_toml_camera_matrix_and_intrinsics_are_the_keywords(tmp_path):
    rotation, position, _ = QUARTER_TURNS[1]
    matrix = pose(rotation, position)
    rows = ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]" for row in matrix)
    scene = tmp_path / "s.toml"
    scene.write_text(
        f"[camera]\nwidth = 20\nheight = 15\nmatrix = [{rows}]\nintrinsics = [18.0, 17.0, 9.5, 7.0]\n\n"
        f'[[mesh]]\nfile = "{CORNELL_OBJ}"\n'
    )
    from_file = raytracer.render(scene)
    from_keywords = raytracer.render(CORNELL_OBJ, width=20, height=15, camera_to_world=matrix, intrinsics=(18, 17, 9.5, 7))
    assert np.array_equal(from_file, from_keywords)
    scene.write_text(f"[camera]\nmatrix = [{rows}]\nup = [0, 1, 0]\n")
    with pytest.raises(raytracer.SceneError, match=r"s.toml:2: camera.matrix: give either a matrix or look_from"):
        raytracer.Scene(scene)
    scene.write_text("[camera]\nmatrix = [[1, 0, 0, 0], [0, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n")
    with pytest.raises(raytracer.SceneError, match=r"s.toml:2: camera.matrix: the rotation part .* is singular"):
        raytracer.Scene(scene)
    scene.write_text("[camera]\nintrinsics = [10, -1, 0, 0]\n")
    with pytest.raises(ValueError, match=r"s.toml:2: camera.intrinsics: .* are not intrinsics"):
        raytracer.render(scene)


@pytest.mark.parametrize(
    "matrix,message",
    [
        (np.diag([1.0, 1.0, 0.0, 1.0]), "is singular"),
        (np.diag([2.0, 2.0, 2.0, 1.0]), "has length 2"),
        (np.diag([1.0, 1.0, -1.0, 1.0]), "mirror image"),
        # Unit columns 0.1 radians from perpendicular.
        (np.array([[1, np.sin(0.1), 0, 0], [0, np.cos(0.1), 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]), "not perpendicular"),
        (np.where(np.eye(4) == 1, np.nan, 0.0), "element \\[0\\]\\[0\\] is NaN"),
        (np.eye(4) + np.array([[0, 0, 0, 0]] * 3 + [[0, 0, 1, 0]]), "the last row"),
        (np.eye(3), "4x4 matrix"),
    ],
)
def test_bad_matrices_are_value_errors_naming_the_argument(matrix, message):
    with pytest.raises(ValueError, match=f"invalid camera_to_world: .*{message}"):
        raytracer.render(CORNELL_OBJ, width=4, height=3, camera_to_world=matrix)
    with pytest.raises(ValueError, match="camera_to_world or look_from"):
        raytracer.render(CORNELL_OBJ, width=4, height=3, camera_to_world=np.eye(4), look_to=(0, 0, -1))


def test_opencv_poses_round_trip():
    rng = np.random.default_rng(3)
    for _ in range(5):
        rvec, t = rng.normal(size=3), rng.normal(size=3)
        camera_to_world = camera_to_world_from_opencv(rvec, t)
        r, t_back = opencv_from_camera_to_world(camera_to_world)
        assert np.allclose(r @ r.T, np.eye(3)) and np.allclose(t_back, t)
        # OpenCV's camera looks down +Z: the renderer's -Z column is the world's view direction.
        ahead_world = r.T @ np.array([0, 0, 1.0])
        assert np.allclose(-camera_to_world[:3, 2], ahead_world)

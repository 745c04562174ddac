"""Camera poses between conventions.

The renderer's ``camera_to_world=`` (and TOML's ``[camera] matrix``) is a 4x4
camera-to-world matrix in OpenGL's, glTF's and Blender's convention: the camera looks
down its -Z axis with +Y up and +X to the right. OpenCV (and COLMAP, and most
computer-vision datasets) give the opposite: a world-to-camera pose ``[R | t]``
(``x_camera = R @ x_world + t``) whose camera looks down +Z with +Y down. Its
intrinsics ``(fx, fy, cx, cy)`` (pixels, the top-left pixel's centre at (0, 0)) are the
renderer's ``intrinsics=`` unchanged.
"""

import numpy as np

#: OpenCV's camera axes in OpenGL's: +Y and +Z turned around (x stays).
_FLIP_YZ = np.diag([1.0, -1.0, -1.0, 1.0])


def camera_to_world_from_opencv(rotation, translation) -> np.ndarray:
    """The renderer's ``camera_to_world`` (4x4, ``float64``) of OpenCV's world-to-camera
    pose: ``rotation`` R (3x3, or a Rodrigues vector of 3 as ``cv2.solvePnP`` returns)
    and ``translation`` t (3), such that ``x_camera = R @ x_world + t``.

    >>> pose = camera_to_world_from_opencv(np.eye(3), [0, 0, 5])  # 5 in front of the origin
    >>> pose[:3, 3]  # the camera stands at -R^T t
    array([ 0.,  0., -5.])
    """
    rotation = np.asarray(rotation, dtype=np.float64)
    if rotation.shape in ((3,), (3, 1), (1, 3)):
        rotation = _rodrigues(rotation.reshape(3))
    if rotation.shape != (3, 3):
        raise ValueError(f"rotation must be a 3x3 matrix or a Rodrigues vector of 3, not of the shape {rotation.shape}")
    translation = np.asarray(translation, dtype=np.float64).reshape(-1)
    if translation.shape != (3,):
        raise ValueError(f"translation must be 3 numbers, not {translation.size}")
    camera_to_world = np.eye(4)
    camera_to_world[:3, :3] = rotation.T
    camera_to_world[:3, 3] = -rotation.T @ translation
    return camera_to_world @ _FLIP_YZ


def opencv_from_camera_to_world(camera_to_world):
    """The inverse of :func:`camera_to_world_from_opencv`: OpenCV's ``(R, t)`` of a
    4x4 camera-to-world matrix in OpenGL's convention."""
    pose = np.asarray(camera_to_world, dtype=np.float64) @ _FLIP_YZ
    rotation = pose[:3, :3].T
    return rotation, -rotation @ pose[:3, 3]


def _rodrigues(vector: np.ndarray) -> np.ndarray:
    """The rotation matrix of a rotation vector (axis times angle), as ``cv2.Rodrigues``."""
    angle = float(np.linalg.norm(vector))
    if angle == 0.0:
        return np.eye(3)
    k = vector / angle
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross

"""mvkp: fast planar image matching (Multiple View Kernel Projection) from Python.

Images are numpy arrays as cv2 gives them: HxW uint8 (gray) or HxWx3 uint8 (BGR).
Options are keyword arguments named as the fields of the C++ options structs,
with the same defaults (see TrainOptions, MatchOptions, ...)::

    import cv2, mvkp
    model = mvkp.train(cv2.imread("poster.jpg"), views=100, seed=42)
    matcher = mvkp.Matcher(model, ratio=0.85)
    result = matcher.match(cv2.imread("frame.jpg"))
    if result.found:
        print(result.homography, result.outline)

Errors are mvkp.Error subclasses carrying the C++ message: InvalidArgumentError
and BadImageError are ValueErrors, IoError is an OSError.
"""
from ._mvkp import *  # noqa: F401,F403
from ._mvkp import __version__  # noqa: F401
from . import _mvkp

__all__ = [n for n in dir(_mvkp) if not n.startswith("_")] + ["to_cv_keypoints"]


def to_cv_keypoints(keypoints):
    """cv2.KeyPoint list from an (n, 7) keypoint array (x, y, size, angle, response, octave, class_id)."""
    import cv2  # only needed here

    return [
        cv2.KeyPoint(float(k[0]), float(k[1]), float(k[2]), float(k[3]), float(k[4]), int(k[5]), int(k[6]))
        for k in keypoints
    ]

"""The image a render returns: a numpy array that shows itself in Jupyter."""

import numpy as np


class Image(np.ndarray):
    """A rendered linear image: a ``float32`` numpy array of shape ``(height, width,
    3)``, row 0 at the top, exactly the values ``raytracer render`` writes to an EXR
    file. It is an ordinary ``numpy.ndarray`` in every way, plus:

    - ``mode``, ``exposure``, ``tonemap``: how the render that made it post-processes
      (what :func:`raytracer.postprocess` needs to make the PNG's pixels);
    - ``_repr_png_()``: Jupyter and IPython show it as the PNG would look.

    Arithmetic on it gives plain arrays (the post-processing it names no longer
    applies to them); slices stay images.
    """

    mode: str
    exposure: float
    tonemap: str

    @classmethod
    def _wrap(cls, array, mode, exposure, tonemap):
        image = array.view(cls)
        image.mode, image.exposure, image.tonemap = mode, exposure, tonemap
        return image

    def __array_finalize__(self, obj):
        self.mode = getattr(obj, "mode", "full")
        self.exposure = getattr(obj, "exposure", 0.0)
        self.tonemap = getattr(obj, "tonemap", "khronos-neutral")

    def __array_wrap__(self, array, context=None, return_scalar=False):
        # Results of ufuncs and reductions are plain arrays and scalars.
        array = np.asarray(array).view(np.ndarray)
        return array[()] if return_scalar or array.ndim == 0 else array

    def postprocess(self) -> np.ndarray:
        """The 8-bit RGB pixels of the PNG, as :func:`raytracer.postprocess` makes them
        for this image's mode, exposure and tone map."""
        from . import postprocess

        return postprocess(self, self.mode, self.exposure, self.tonemap)

    def _repr_png_(self):
        if self.ndim != 3 or self.shape[2] != 3 or self.size == 0:
            return None
        from ._raytracer import _png

        return _png(self, self.mode, self.exposure, self.tonemap)

"""The progress bar of ``render(..., progress=True)``: a tqdm bar counting rows."""


class TqdmProgress:
    """A callable taking ``(done, total)`` rows that draws a tqdm bar, made on the first
    call (when the total is known); ``close()`` ends it. tqdm is an optional dependency
    (``pip install tqdm``): asking for a bar without it raises ``ImportError`` naming it."""

    def __init__(self):
        try:
            from tqdm.auto import tqdm
        except ImportError as error:
            raise ImportError(
                "render(..., progress=True) draws a tqdm bar: install tqdm "
                "(pip install tqdm) or pass a callable taking (done, total)"
            ) from error
        self._tqdm = tqdm
        self._bar = None

    def __call__(self, done: int, total: int) -> None:
        if self._bar is None:
            self._bar = self._tqdm(total=total, unit="row", desc="render")
        self._bar.update(done - self._bar.n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()

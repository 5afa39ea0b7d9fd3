"""The live preview page of ``snell render --preview``, for renders run from
Python (a distributed render, or a loop of your own).

    with snell.Preview(port=0) as preview:
        print(preview.url)            # open it in a browser
        preview.update(image, spp_done=16, spp_total=256)

The server (Rust, on a thread of its own) listens on 127.0.0.1 unless told
otherwise and answers the page, ``/progress`` (JSON) and ``/image`` (the
latest image as floats), as for the command line. ``update`` never waits on
a browser. The page's Stop button sets :attr:`Preview.stop_requested`.
"""

from __future__ import annotations

from typing import Any, Optional, Tuple

import numpy as np

from . import _snell


class Preview:
    """A running preview server. ``port=0`` picks a free port; ``mode``
    (default: the current variant) tells the page whether to expect Stokes
    layers; ``size`` = (width, height) is what it shows before the first
    image. Stop it with :meth:`close` (or use it as a context manager)."""

    def __init__(self, port: int = 0, *, mode: Optional[str] = None, size: Tuple[int, int] = (1, 1), host: str = "127.0.0.1") -> None:
        from . import _mode

        self._native = _snell.Preview(int(port), _mode(mode), int(size[0]), int(size[1]), host)
        self._updates = 0

    @property
    def url(self) -> str:
        """The page's address, e.g. ``http://127.0.0.1:8730/``."""
        return self._native.url

    @property
    def port(self) -> int:
        return self._native.port

    @property
    def stop_requested(self) -> bool:
        """Whether the page's Stop button was pressed."""
        return self._native.stop_requested

    def update(self, image_or_state: Any, spp_done: int, spp_total: int, *, pass_: Optional[int] = None, passes: Optional[int] = None) -> None:
        """Shows an image: an (H, W, C) array (its first three channels are
        R, G, B; one channel is grey) or a film state (``bytes``, as the
        tasks of :mod:`snell.distributed` return), with ``spp_done`` of
        ``spp_total`` samples per pixel. ``pass_`` of ``passes`` is what the
        page calls the update (default: the updates so far)."""
        self._updates += 1
        p = self._updates if pass_ is None else int(pass_)
        n = (p if spp_done >= spp_total else p + 1) if passes is None else int(passes)
        if isinstance(image_or_state, (bytes, bytearray, memoryview)):
            self._native.publish(bytes(image_or_state), None, 0, 0, [], p, n, int(spp_done), int(spp_total))
            return
        a = np.asarray(image_or_state, dtype=np.float32)
        if a.ndim == 2:
            a = a[:, :, None]
        if a.ndim != 3 or a.shape[2] < 1:
            raise ValueError(f"expected an (H, W, C) image, got an array of shape {a.shape}")
        if a.shape[2] >= 3:
            a, names = a[:, :, :3], ["R", "G", "B"]
        else:
            a, names = a[:, :, :1], ["Y"]
        a = np.ascontiguousarray(a)
        self._native.publish(None, a.tobytes(), a.shape[0], a.shape[1], names, p, n, int(spp_done), int(spp_total))

    def finish(self, interrupted: bool = False) -> None:
        """Marks the render as over (done, or stopped early)."""
        self._native.finish(interrupted)

    def close(self) -> None:
        """Stops the server."""
        self._native.close()

    def __enter__(self) -> "Preview":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

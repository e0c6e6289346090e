"""Progress helpers for ``prt.bake`` and ``prt.reference``."""

import sys
import warnings

from ._errors import PrtWarning

__all__ = ["TqdmProgress", "PrintProgress"]


class TqdmProgress:
    """A progress callback drawing one tqdm bar per stage; notes go through ``tqdm.write``,
    warnings are issued as ``prt.PrtWarning``. Keyword arguments go to each bar
    (``tqdm.auto.tqdm``, so a notebook gets its widget).

    >>> prt.bake("scenes/cornell", out="/tmp/c.prtbake", progress=prt.TqdmProgress())
    """

    def __init__(self, notes=True, **tqdm_kwargs):
        try:
            from tqdm.auto import tqdm
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("TqdmProgress needs tqdm: pip install tqdm") from e
        self._tqdm = tqdm
        self._notes = notes
        self._kwargs = tqdm_kwargs
        self._bar = None

    def __call__(self, event):
        if event.kind == "start":
            self._close()
            self._bar = self._tqdm(total=event.total, desc=event.stage, **self._kwargs)
        elif event.kind in ("advance", "restored") and self._bar is not None:
            self._bar.update(event.steps)
        elif event.kind == "finish":
            self._close()
        elif event.kind == "note" and self._notes:
            self._tqdm.write(event.text)
        elif event.kind == "warning":
            warnings.warn(event.text, PrtWarning, stacklevel=2)

    def _close(self):
        if self._bar is not None:
            self._bar.close()
            self._bar = None


class PrintProgress:
    """A progress callback printing a line per stage, at each tenth of it, and every note
    and warning (to ``file``, default stderr): for logs, where bars do not draw."""

    def __init__(self, file=None):
        self._file = file
        self._tenth = 0

    def __call__(self, event):
        out = self._file if self._file is not None else sys.stderr
        if event.kind == "start":
            self._tenth = 0
            print(f"{event.stage}: {event.total} steps", file=out)
        elif event.kind in ("advance", "restored") and event.total:
            tenth = event.done * 10 // event.total
            if tenth > self._tenth:
                self._tenth = tenth
                print(f"{event.stage}: {event.done}/{event.total}", file=out)
        elif event.kind == "note":
            print(event.text, file=out)
        elif event.kind == "warning":
            print(f"warning: {event.text}", file=out)

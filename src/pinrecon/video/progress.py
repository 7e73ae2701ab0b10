"""A progress bar over a video's frames: tqdm's when it is installed (the ``video`` extra
brings it), else one plain line on stderr rewritten in place (a line per tenth when stderr is
a file)."""

from __future__ import annotations

import sys
import threading
import time

__all__ = ["FrameProgress"]


class FrameProgress:
    """``with FrameProgress(total, "track cam01.mp4") as bar: bar.update()`` per frame (from any
    thread).

    ``enabled=False`` prints nothing; ``total`` may be 0 (unknown length); ``file``: where to
    (default stderr)."""

    def __init__(self, total: int, desc: str, *, enabled: bool = True, unit: str = "frame", file=None):
        self.total, self.desc, self.enabled, self.unit = int(total or 0), desc, enabled, unit
        self.file = sys.stderr if file is None else file
        self.n, self.t0, self._bar, self._last = 0, time.perf_counter(), None, -1
        self._lock = threading.Lock()  # frames may come from several threads
        if not enabled:
            return
        try:
            from tqdm import tqdm
        except ImportError:
            return
        self._bar = tqdm(total=self.total or None, desc=desc, unit=unit, file=self.file, leave=True,
                         dynamic_ncols=True)

    def update(self, n: int = 1) -> None:
        with self._lock:
            self._update(n)

    def _update(self, n: int) -> None:
        self.n += n
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.update(n)
            return
        tty = self.file.isatty()
        step = max(1, self.total // 10) if self.total else 50
        if tty or self.n // step != self._last or self.n == self.total:
            self._last = self.n // step
            rate = self.n / max(time.perf_counter() - self.t0, 1e-9)
            of = f"/{self.total}" if self.total else ""
            line = f"{self.desc}: {self.n}{of} {self.unit}s, {rate:.1f}/s"
            print(("\r" + line.ljust(70)) if tty else line, end="" if tty else "\n", file=self.file, flush=True)

    def close(self) -> None:
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.close()
        elif self.file.isatty():
            print(file=self.file)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

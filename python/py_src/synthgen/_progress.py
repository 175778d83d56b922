"""Progress the Python way: a tqdm-style bar on stderr (only when stderr is a terminal),
warnings and informational lines through the ``synthgen`` logger."""

from __future__ import annotations

import logging
import sys
import time
from typing import Callable, Optional, TextIO, Union

logger = logging.getLogger("synthgen")

#: A progress callback as the native module calls it: ``callback(event, text, n)``.
ProgressCallback = Callable[[str, str, int], None]


class ProgressBar:
    """Draws ``label  42%|████▏     | 42/100 [00:03<00:04, 13.1 frames/s]`` on ``file``.

    ``enabled=None`` shows the bar only when ``file`` is a terminal. Warnings always go to the
    ``synthgen`` logger (printed on stderr unless logging is configured otherwise); info lines
    go to it at INFO level.
    """

    def __init__(
        self,
        enabled: Optional[bool] = None,
        file: Optional[TextIO] = None,
        unit: str = "frames",
    ) -> None:
        self.file = file if file is not None else sys.stderr
        if enabled is None:
            isatty = getattr(self.file, "isatty", None)
            enabled = bool(isatty and isatty())
        self.enabled = enabled
        self.unit = unit
        self.label = ""
        self.total = 0
        self.done = 0
        self.started = time.monotonic()
        self._drawn = 0.0

    def __call__(self, event: str, text: str, n: int) -> None:
        if event == "start":
            self.label, self.total, self.done = text, n, 0
            self.started = time.monotonic()
            self._draw(force=True)
        elif event == "advance":
            self.done += n
            self._draw()
        elif event == "warn":
            self._clear()
            logger.warning(text)
            self._draw(force=True)
        elif event == "info":
            logger.info(text)
        elif event == "finish":
            self._draw(force=True)
            if self.enabled and self.label:
                self.file.write("\n")
                self.file.flush()
            self.label = ""

    def _clear(self) -> None:
        if self.enabled and self.label:
            self.file.write("\r\033[K")

    def _draw(self, force: bool = False) -> None:
        if not self.enabled or not self.label:
            return
        now = time.monotonic()
        if not force and now - self._drawn < 0.1:
            return
        self._drawn = now
        elapsed = now - self.started
        rate = self.done / elapsed if elapsed > 0 else 0.0
        if self.total:
            frac = min(1.0, self.done / self.total)
            width = 20
            full = int(frac * width)
            bar = "█" * full + " " * (width - full)
            left = (self.total - self.done) / rate if rate > 0 else 0.0
            line = (
                f"{self.label} {100 * frac:3.0f}%|{bar}| {self.done}/{self.total} "
                f"[{_clock(elapsed)}<{_clock(left)}, {rate:.1f} {self.unit}/s]"
            )
        else:
            line = f"{self.label} {self.done} [{_clock(elapsed)}, {rate:.1f} {self.unit}/s]"
        self.file.write("\r" + line)
        self.file.flush()


def _clock(seconds: float) -> str:
    m, s = divmod(int(seconds), 60)
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m:02d}:{s:02d}"


def log_only(event: str, text: str, n: int) -> None:
    """A callback that shows no bar: warnings and info lines to the ``synthgen`` logger."""
    if event == "warn":
        logger.warning(text)
    elif event == "info":
        logger.info(text)


def callback(progress: Union[bool, None, ProgressCallback]) -> ProgressCallback:
    """``True``: always a bar; ``False``: never; ``None``: a bar when stderr is a terminal; a
    callable is used as it is."""
    if callable(progress):
        return progress
    if progress is False:
        return log_only
    return ProgressBar(enabled=True if progress else None)

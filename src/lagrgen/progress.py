"""A progress bar for long runs (tqdm), driven by the simulated time reached."""
import sys
import time


class ProgressBar:
    """Shows how far a run from t0 to t1 has got on stderr.

    `show` is True (always), False (never) or "auto": only on a terminal, and only once the run
    has taken longer than `delay` seconds (so short runs print nothing).
    """

    def __init__(self, t0, t1, show=True, delay=1.0, desc="simulate", stream=None,
                 mininterval=0.1):
        self.t0, self.t1, self.desc, self.mininterval = float(t0), float(t1), desc, mininterval
        self.stream = sys.stderr if stream is None else stream
        self.auto = show == "auto"
        self.enabled = bool(show) and (not self.auto or self.stream.isatty())
        self.start = time.monotonic()
        self.delay = delay if self.auto else 0.0
        self.bar = None
        if self.enabled and not self.auto:
            self._open()

    def _open(self):
        from tqdm import tqdm
        self.bar = tqdm(total=abs(self.t1 - self.t0) or 1.0, desc=self.desc, file=self.stream,
                        leave=True, dynamic_ncols=True, mininterval=self.mininterval,
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| {unit} "
                                   "[{elapsed}<{remaining}]", unit=self._where(self.t0))

    def __call__(self, t):
        """Report that the run has reached time t."""
        if not self.enabled:
            return
        if self.bar is None:
            if time.monotonic() - self.start < self.delay:
                return
            self._open()
        done = min(abs(float(t) - self.t0), self.bar.total)
        self.bar.unit = self._where(t)
        self.bar.update(done - self.bar.n)

    def _where(self, t):
        return f"t = {float(t):.4g} of {self.t1:.4g}"

    def close(self, t=None):
        """Finish the bar (at time t when given)."""
        if self.bar is not None:
            if t is not None:
                self(t)
            self.bar.close()
            self.bar = None

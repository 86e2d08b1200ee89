"""Joint records made ready for identification: checked as (n, N) rows per joint, and, when only
positions are recorded, velocities and accelerations by a zero-phase low-pass and central
differences, the torques filtered alike, all decimated to uncorrelated samples."""
import math
from dataclasses import dataclass

import numpy as np

from ..fit import sample_times

#: The order of the zero-phase Butterworth low-pass applied to the positions (and torques).
FILTER_ORDER = 4

#: The cut-off is CUTOFF_FACTOR times the highest frequency of the motion: the filter (applied
#: forwards and backwards) then passes the motion with a gain 1 − (1/5)^8 ≈ 1 − 3e-6.
CUTOFF_FACTOR = 5.0

#: How many periods of the cut-off frequency are dropped at each end of filtered records.
EDGE_PERIODS = 4


def _records(mod, t, q, tau, qd, qdd):
    """t (N,), and q, tau, qd, qdd as (n, N) float arrays (qd, qdd None when not given)."""
    t = sample_times(t)
    n, N = mod.n_coordinates, t.size
    arrays = [_joint_record(x, name, n, N) if x is not None else None
              for x, name in ((q, "q"), (tau, "tau"), (qd, "qd"), (qdd, "qdd"))]
    return (t, *arrays)


def _joint_record(x, name, n, N):
    """A record of the n joints at N times as an (n, N) array; a clear error for (N, n)."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 1 and n == 1:
        x = x[None, :]
    if x.shape != (n, N):
        hint = (f": transpose it ({name}.T)" if x.shape == (N, n) else "")
        raise ValueError(f"{name} must have shape (n, len(t)) = ({n}, {N}), one row per joint "
                         f"as sol.q has, got {x.shape}{hint}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite (drop or interpolate missing samples)")
    return x


def motion_bandwidth(q, rate):
    """The highest frequency (Hz) of the joints' motion: the largest of `joint_bandwidths`; a
    ValueError when no joint moves."""
    highest = float(joint_bandwidths(q, rate).max(initial=0.0))
    if highest == 0.0:
        raise ValueError("the positions do not move: identification needs a motion (see "
                         "lagrgen.exciting_trajectory)")
    return highest


def joint_bandwidths(q, rate):
    """Each joint's highest frequency of motion (Hz): where the Hann-windowed periodogram of its
    detrended positions last exceeds 1e-6 of its peak (the motion's content down to 1e-3 of its
    largest amplitude) and 100 times the noise floor (the median over the upper half of the
    band, where no motion is); 0 for a joint whose spectrum never rises that far above its floor
    (held still: its encoder's noise alone)."""
    from scipy.signal import detrend
    N = q.shape[1]
    power = np.abs(np.fft.rfft(detrend(q, axis=1) * np.hanning(N), axis=1)) ** 2
    freqs = np.fft.rfftfreq(N, 1.0 / rate)
    floor = np.median(power[:, freqs > rate / 4], axis=1) if N >= 8 else np.zeros(len(q))
    highest = np.zeros(len(q))
    for j, (p, f0) in enumerate(zip(power, floor)):
        above = np.flatnonzero(p > max(1e-6 * p.max(), 100 * f0))
        if p.max() > 0 and above.size:
            highest[j] = freqs[above].max()
    return highest


def _uniform_rate(t):
    """1/Δt of uniformly sampled times; ValueError otherwise."""
    dt = np.diff(t)
    if np.max(np.abs(dt - dt.mean())) > 1e-6 * dt.mean():
        raise ValueError("t must be uniformly sampled to estimate velocities and accelerations "
                         "(resample the records, or give qd and qdd)")
    return 1.0 / dt.mean()


def _uncorrelated_step(sos, span):
    """The first lag (samples) at which white noise filtered forwards and backwards by the
    second-order sections `sos` is uncorrelated: the first zero of the autocorrelation of its
    impulse response."""
    from scipy.signal import sosfiltfilt
    impulse = np.zeros(4 * span + 1)
    impulse[2 * span] = 1.0
    h = sosfiltfilt(sos, impulse)
    r = np.correlate(h, h, "full")[h.size - 1:]
    crossing = np.flatnonzero(r <= 0)
    return int(crossing[0]) if crossing.size else span


@dataclass
class FilteredRecords:
    """The samples identification uses: times, positions, velocities, accelerations and torques
    (each (n, m)), with the filter's cut-off (Hz, None when unfiltered) and decimation step."""
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    cutoff: float = None
    step: int = 1


def filtered_records(t, q, tau, cutoff=None):
    """Velocities and accelerations from positions, Gautier's way: a zero-phase Butterworth
    low-pass (order FILTER_ORDER, forwards and backwards) of q at `cutoff` Hz (None:
    CUTOFF_FACTOR times `motion_bandwidth`, so the motion passes unchanged and the noise above
    it is removed), then central differences q̇_i = (q_{i+1} − q_{i−1})/2Δt and
    q̈_i = (q_{i+1} − 2q_i + q_{i−1})/Δt². The torques get the same filter, and all records are
    decimated to one sample per first zero of the autocorrelation of white noise through the
    filter (about 0.56/cutoff s): the filtered noise of the samples kept is uncorrelated again,
    so the standard errors stay honest, with fewer regressor calls. The first and last
    EDGE_PERIODS/cutoff seconds are dropped: there the filter has no past or future, and its
    start-up transient (the records' ends reflected oddly) has not decayed below about 1e-4 of
    the motion. A joint held still (no motion above its noise, `joint_bandwidths`) is recorded
    at its mean position with q̇ = q̈ = 0, so that the directions only its motion would excite
    are reported as the records' blind spots (as with q̇ and q̈ given), not fitted to noise."""
    from scipy.signal import butter, sosfiltfilt
    rate = _uniform_rate(t)
    still = joint_bandwidths(q, rate) == 0.0
    cutoff = CUTOFF_FACTOR * motion_bandwidth(q, rate) if cutoff is None else float(cutoff)
    if not 0 < cutoff < 0.45 * rate:
        raise ValueError(f"the filter's cut-off must lie between 0 and 0.45 times the sampling "
                         f"rate ({0.45 * rate:.6g} Hz), got {cutoff:.6g} Hz: sample faster, or "
                         "give cutoff=... (Hz) or qd and qdd")
    sos = butter(FILTER_ORDER, cutoff / (rate / 2), output="sos")
    qf, tauf = sosfiltfilt(sos, q, axis=1), sosfiltfilt(sos, tau, axis=1)
    dt = 1.0 / rate
    qd = (qf[:, 2:] - qf[:, :-2]) / (2 * dt)
    qdd = (qf[:, 2:] - 2 * qf[:, 1:-1] + qf[:, :-2]) / dt ** 2
    qf[still] = qf[still].mean(axis=1, keepdims=True)      # held still: its noise is no motion
    qd[still] = qdd[still] = 0.0
    step = _uncorrelated_step(sos, int(math.ceil(2 * rate / cutoff)))
    edge = int(math.ceil(EDGE_PERIODS * rate / cutoff))
    keep = np.arange(edge, t.size - 2 - edge, step)
    if keep.size < 2:
        raise ValueError(f"the records are too short for a filter at {cutoff:.6g} Hz: record "
                         f"longer than {3 * EDGE_PERIODS / cutoff:.3g} s, or give qd and qdd")
    inner = keep + 1
    return FilteredRecords(t[inner], qf[:, inner], qd[:, keep], qdd[:, keep], tauf[:, inner],
                           cutoff, step)

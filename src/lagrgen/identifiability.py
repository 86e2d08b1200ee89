"""What data can determine: the directions of the estimated names a least-squares fit does not see,
their covariance on the directions it does, and estimates on their bounds — shared by `lagrgen.fit`,
`lagrgen.fit_modes` and the standard errors of `lagrgen.Collocation` (`collocation.statistics`).

With the Jacobian J of the weighted residuals by the k names, columns scaled to unit norm, a
singular value below the Jacobian's own accuracy is taken as zero: its right singular vector is a
direction the data do not see. Such a direction gets an infinite variance and an
`IdentifiabilityWarning` naming the combination, never the zero variance of a pseudo-inverse nor
the small one of a regularization; the covariance s²·(JᵀJ)⁻¹ holds on the directions J sees.
"""
import warnings

import numpy as np


#: Singular values of the column-normalized Jacobian below UNSEEN_FACTOR times the Jacobian's own
#: accuracy (the solver's rtol for `fit`, the difference step for `fit_modes`), and never below
#: UNSEEN_MAX, are taken as zero: the data do not see that direction.
UNSEEN_FACTOR = 10.0
UNSEEN_MAX = 1e-3


class FitWarning(UserWarning):
    """The data do not determine every fitted name, or an estimate sits on its bound."""


class IdentifiabilityWarning(FitWarning):
    """The data do not determine every estimated name: some combination of them leaves the fit
    unchanged (their standard errors are infinite); given by `fit`, `fit_modes`,
    `identify_inertial` and collocation's standard errors."""


def unseen_directions(J, names, accuracy):
    """(rank, directions, Vt, s, scale) of the Jacobian J (m, k): with its columns scaled to
    unit norm (`scale`), J/scale = U·diag(s)·Vt, singular values below UNSEEN_FACTOR·accuracy
    taken as zero; `directions` are the null directions δθ = v/scale (dicts name -> component,
    largest 1), a column of zeros its own direction."""
    scale = np.linalg.norm(J, axis=0)
    safe = np.where(scale > 0, scale, 1.0)
    # Vt whole (k × k) without the m × m U of a tall J: full matrices only when J is wide
    _, s, Vt = np.linalg.svd(J / safe, full_matrices=J.shape[0] < J.shape[1])
    tol = min(UNSEEN_FACTOR * accuracy, UNSEEN_MAX) * max(1.0, s.max(initial=0.0))
    rank = int(np.sum(s > tol))
    directions = []
    for v in Vt[rank:]:
        involved = np.abs(v) > 1e-6
        d = np.where(involved, v / safe, 0.0)
        d = d / np.abs(d).max()
        d = d * np.sign(d[np.argmax(involved)])
        directions.append({n: float(c) for n, c, i in zip(names, d, involved) if i})
    return rank, directions, Vt, s, scale


def covariance(J, s2, names, accuracy):
    """(cov, unidentified names, unseen directions): s²·(JᵀJ)⁻¹ on the directions J sees; a
    name with a component along an unseen direction has variance inf (its covariances NaN)."""
    k = len(names)
    rank, directions, Vt, s, scale = unseen_directions(J, names, accuracy)
    Vr, sr = Vt[:rank].T, s[:rank]
    safe = np.where(scale > 0, scale, 1.0)
    cov = (Vr / sr ** 2) @ Vr.T * s2 / np.outer(safe, safe)
    involved = [i for i in range(k) if any(names[i] in d for d in directions)]
    for i in involved:
        cov[i, :] = cov[:, i] = np.nan
        cov[i, i] = np.inf
    return cov, tuple(names[i] for i in involved), directions


def warn_unseen(directions, rank, k, consequence="their standard errors are reported as inf",
                advice="Fit fewer names, fix the others at known values with p={...}, or "
                "measure more",
                stacklevel=3):
    """An IdentifiabilityWarning naming the names the data do not determine and the
    combinations along which the fit does not change (`directions`)."""
    combos = "; ".join(f"{next(iter(d))} alone" if len(d) == 1 else
                       " : ".join(f"δ({n})" if " " in n else f"δ{n}" for n in d) + " = " +
                       " : ".join(f"{c:.3g}" for c in d.values()) for d in directions)
    which = [n for n in dict.fromkeys(n for d in directions for n in d)]
    warnings.warn(f"the data do not determine {', '.join(which)} (the Jacobian has rank {rank} "
                  f"of {k}): the fit does not change when the estimates move along {combos}; "
                  f"{consequence}. {advice}", IdentifiabilityWarning, stacklevel=stacklevel)


def on_bounds(x, low, high, names, stacklevel=3):
    """The names whose estimate is on a finite bound, with a FitWarning naming them."""
    tol = 1e-10 * np.maximum(1.0, np.abs(x))
    hit = {n: f"{n} = {v:.6g} ({'lower' if v - lo <= tl else 'upper'} bound)"
           for n, v, lo, hi, tl in zip(names, x, low, high, tol)
           if v - lo <= tl or hi - v <= tl}
    if hit:
        warnings.warn(f"estimates on their bounds: {', '.join(hit.values())}; the data pull "
                      "them past the bound, and their standard errors assume they are free",
                      FitWarning, stacklevel=stacklevel)
    return tuple(hit)

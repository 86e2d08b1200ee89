"""Planar n-link pendulum: a chain of n massless links with point masses at their ends.

Link i (i = 0 … n−1) has length l_i and carries the point mass m_i at its far end; the first link
hangs from a fixed pivot. The coordinates q_i are the absolute angles of the links from the
downward vertical; gravity g acts in −y.

    p_k = Σ_{i≤k} l_i·(sin q_i, −cos q_i),   T = Σ ½·m_k·|ṗ_k|²,   V = Σ m_k·g·y_k

`make(n, name=None)` returns the n-link model (named "nlink<n>" unless `name` is given); `model`
is the three-link one.
"""
import sympy as sp

from lagrgen import Model


def make(n, name=None):
    """Return the n-link pendulum Model, parameters m0 … m(n−1), l0 … l(n−1), g."""
    model = Model(name or f"nlink{n}")
    q = model.coordinates([f"q{i}" for i in range(n)])
    masses = model.parameters(**{f"m{i}": 1.0 for i in range(n)})
    lengths = model.parameters(**{f"l{i}": 1.0 for i in range(n)})
    g, = model.parameters(g=9.81)
    points = [sp.Matrix([0, 0])]
    for i in range(n):
        points.append(points[-1] + lengths[i] * sp.Matrix([sp.sin(q[i]), -sp.cos(q[i])]))
        model.particle(masses[i], points[-1])
        model.potential_energy(masses[i] * g * points[-1][1])
    model.line(*points)
    return model


model = make(3)

"""Serial chains of revolute joints as URDF text, for benchmarks/robots.py (issues 43 and 45): n
links with random masses, centres, inertias (positive definite, triangle inequality held),
placements (offsets and rotations) and axes cycling through z, y, x."""
import numpy as np


def chain_urdf(n, seed=0):
    """The URDF text of a 3-D chain of n revolute joints (reproducible from `seed`)."""
    rng = np.random.default_rng(seed)
    parts = [f'<?xml version="1.0"?><robot name="chain{n}">', '<link name="l0"/>']
    for k in range(1, n + 1):
        m = rng.uniform(0.5, 2.0)
        c = rng.uniform(-0.05, 0.05, 3)
        d = rng.uniform(0.015, 0.025, 3)
        off = rng.uniform(-0.002, 0.002, 3)
        parts.append(
            f'<link name="l{k}"><inertial><origin xyz="{c[0]} {c[1]} {c[2]}" rpy="0 0 0"/>'
            f'<mass value="{m}"/><inertia ixx="{d[0]}" ixy="{off[0]}" ixz="{off[1]}" '
            f'iyy="{d[1]}" iyz="{off[2]}" izz="{d[2]}"/></inertial></link>')
        axis = ("0 0 1", "0 1 0", "1 0 0")[k % 3]
        xyz = rng.uniform(-0.1, 0.1, 3)
        xyz[2] += 0.2
        rpy = rng.uniform(-0.5, 0.5, 3)
        parts.append(
            f'<joint name="j{k}" type="revolute"><parent link="l{k - 1}"/><child link="l{k}"/>'
            f'<origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/>'
            f'<axis xyz="{axis}"/><limit lower="-3" upper="3" velocity="5" effort="100"/>'
            '</joint>')
    parts.append("</robot>")
    return "".join(parts)

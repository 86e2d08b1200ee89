"""Inertial identification of robots: the regressor, base parameters, identification from joint
records and exciting trajectories, a package of those stages.

The equations of a chain of rigid links are linear in the ten inertial parameters of each link,
π = (m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz) per link (mass, mass times the centre of mass
and the inertia about the link frame's origin, in the link frame):

    M(q)·q̈ − F(q, q̇) = Y(q, q̇, q̈)·π        (inputs, springs and dampers left out of F)

with Y, n × 10·links, the regressor. Some columns of Y are zero (a parameter with no effect) and
others are combinations of earlier ones (a link's mass acting only through its parent's
parameters): only the base parameters π_b = K·π, r of them, are identifiable, and Y·π = Y_b·π_b
with Y_b the r independent columns of Y. Least squares on τ = Y_b·π_b over the samples of a
motion estimates them; a motion whose stacked Y_b is well conditioned (an exciting trajectory)
estimates them well.
"""
from .regressor import (FIELDS, inertial_parameters_of, links_of, regressor_of,
                        stacked_regressor)
from .base import BASE_TOL, PREFERENCE, BaseParameters, base_parameters
from .records import (CUTOFF_FACTOR, EDGE_PERIODS, FILTER_ORDER, FilteredRecords,
                      filtered_records, motion_bandwidth)
from .consistency import BASIS, CONSISTENT_GAP, pseudo_inertia
from .estimation import REGRESSOR_ACCURACY, InertialEstimate, identify_inertial
from .trajectories import ExcitingTrajectory, exciting_trajectory

__all__ = ["FIELDS", "inertial_parameters_of", "links_of", "regressor_of", "stacked_regressor",
           "BASE_TOL", "PREFERENCE", "BaseParameters", "base_parameters", "CUTOFF_FACTOR",
           "EDGE_PERIODS", "FILTER_ORDER", "FilteredRecords", "filtered_records",
           "motion_bandwidth", "BASIS", "CONSISTENT_GAP", "pseudo_inertia", "REGRESSOR_ACCURACY",
           "InertialEstimate", "identify_inertial", "ExcitingTrajectory", "exciting_trajectory"]

"""Grasp analysis: grasp matrix, hand Jacobian, wrench spaces and quality.

Pure numpy/scipy, following the notation of "Robot Grasping Foundations"
(sec. 2.2-2.3): contact points c_i, frames R_i = (n_i, l_i, o_i) with n_i
into the object, reference point p, torque scale rho, selection matrices
B_i, partial grasp matrices G~_i, grasp matrix G, hand Jacobian J = B J~ and
grasp Jacobian G_J.  Tolerances live in ``planner.quality.tolerances``.
"""

from planner.geometry.mass import radius_of_gyration, torque_scale_max_distance
from planner.quality.contacts import MODELS, NORMS, Contacts, as_contacts
from planner.quality.forces import contact_forces
from planner.quality.grasp_matrix import grasp_matrix, partial_grasp_matrix, selection_matrix, skew
from planner.quality.jacobian import JOINT_TYPES, grasp_jacobian, hand_jacobian
from planner.quality.metrics import Quality, epsilon, evaluate, force_closure, volume
from planner.quality.resistance import HandDrive, Resistance, weight_resistance
from planner.quality.tolerances import FORCE_CLOSURE_TOL
from planner.quality.wrenches import PrimitiveWrenches, primitive_wrenches

__all__ = [
    "FORCE_CLOSURE_TOL", "JOINT_TYPES", "MODELS", "NORMS", "Contacts", "HandDrive", "PrimitiveWrenches",
    "Resistance", "weight_resistance",
    "Quality", "as_contacts", "contact_forces", "epsilon", "evaluate", "force_closure",
    "grasp_jacobian", "grasp_matrix", "hand_jacobian", "partial_grasp_matrix",
    "primitive_wrenches", "radius_of_gyration", "selection_matrix", "skew",
    "torque_scale_max_distance", "volume",
]

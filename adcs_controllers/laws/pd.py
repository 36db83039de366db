"""Quaternion PD benchmark law of seed 004 (Horri, Palmer & Roberts), eq. (13).

    u_PD = -kp I q - kd I w                                   (seed 004, eq. 13)

``q`` is the vector part of the attitude quaternion (scalar last) and ``I`` the inertia matrix:
the gains are multiplied by the inertia (seed 004 III.F: "PD gains are multiplied by the moment
of inertia I"). Regulating to a commanded attitude ``q_c`` / rate ``w_c`` uses the error
quaternion ``q_c* ⊗ q`` and ``w - w_c`` (our extension; with the identity and zero rate it is
exactly eq. 13). As printed, the law does not flip the sign of ``q`` when ``q4 < 0`` (it would then
rotate the long way round); ``shortest_path=True`` applies that usual flip.
"""
from __future__ import annotations

import numpy as np

from adcs_controllers.laws.base import TARGET_PARAMS, SectionLaw, shortest_path_param
from adcs_core.attitude import error_quaternion, matvec


def pd_torque(q: np.ndarray, w: np.ndarray, inertia: np.ndarray, kp, kd,
              q_ref: np.ndarray | None = None, w_ref: np.ndarray | None = None,
              shortest_path: bool = False) -> np.ndarray:
    """Body torque of eq. (13). Shapes: q (..., 4), w (..., 3), inertia (3, 3) or (..., 3, 3).

    ``kp``, ``kd`` are scalars or arrays broadcasting against the batch axes.
    """
    qe = q if q_ref is None else error_quaternion(q, q_ref)
    we = w if w_ref is None else w - w_ref
    qv = qe[..., :3]
    if shortest_path:
        qv = np.where(qe[..., 3:4] < 0, -qv, qv)
    kp = np.asarray(kp, dtype=float)[..., None] if np.ndim(kp) else kp
    kd = np.asarray(kd, dtype=float)[..., None] if np.ndim(kd) else kd
    return -matvec(inertia, kp * qv + kd * we)


PD_SHORTEST_PATH = shortest_path_param(
    'flip q when q4 < 0 (not in seed 004 eq. 13, which is applied as printed by default)')


# PD's one mode, numbered apart from the other laws' codes (0-6): seed 000's reconfiguration flies PD
# before the two-wheel laws, and the published mode_index tells them apart
MODE_PD = 10


class PdLaw(SectionLaw):
    """Eq. (13) bound to a validated ``pd_controller`` section (values may carry a batch axis).

    The object the node and the batch engine both call: ``control(t, q, w) -> (torque, status)``.
    """

    params = (*TARGET_PARAMS, PD_SHORTEST_PATH)
    mode_names = {MODE_PD: 'pd'}

    def __init__(self, p) -> None:
        p = self.section(p)
        super().__init__(p)
        self.kp, self.kd = p.kp, p.kd
        self.shortest_path = p.shortest_path

    def control(self, t: float, q: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, dict]:
        u = pd_torque(q, w, self.inertia, self.kp, self.kd, self.q_ref, self.w_ref, self.shortest_path)
        return u, {'mode': 'pd'}

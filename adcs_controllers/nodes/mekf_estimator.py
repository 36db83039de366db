"""MekfEstimator node: the mekf_estimator family (adcs_controllers/estimators/families.py) on the graph:
the fitted sensors of each step in, estimate/state and estimator/status out (nodes/estimator_base.py)."""
from __future__ import annotations

from adcs_controllers.estimators.families import MEKF
from adcs_controllers.nodes.estimator_base import EstimatorNode
from adcs_msgs_py.node import entry_point


class MekfEstimator(EstimatorNode):
    family = MEKF


main = entry_point(MekfEstimator)

if __name__ == '__main__':
    main()

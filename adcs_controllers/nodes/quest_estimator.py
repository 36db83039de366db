"""QuestEstimator node: the quest_estimator family (adcs_controllers/estimators/families.py) on the graph:
the fitted sensors of each step in, estimate/state and estimator/status out (nodes/estimator_base.py)."""
from __future__ import annotations

from adcs_controllers.estimators.families import QUEST
from adcs_controllers.nodes.estimator_base import EstimatorNode
from adcs_msgs_py.node import entry_point


class QuestEstimator(EstimatorNode):
    family = QUEST


main = entry_point(QuestEstimator)

if __name__ == '__main__':
    main()

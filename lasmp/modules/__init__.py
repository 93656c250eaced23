"""LAS-MP networks: implicit encoder, history estimators, composed actor and its export."""

from lasmp.modules.encoder import ImplicitEncoder
from lasmp.modules.estimator import HistoryEstimator
from lasmp.modules.policy import LasmpActor, LasmpDeployPolicy

__all__ = ["HistoryEstimator", "ImplicitEncoder", "LasmpActor", "LasmpDeployPolicy"]

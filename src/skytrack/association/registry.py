"""Registries of association parts: scorers and assigners by name.

Adding a rule (fuzzy, maximum-likelihood, greedy, sequential...) is one module plus one
entry here; the tracker's ``association`` configuration section names them.
"""

from __future__ import annotations

from functools import partial

from skytrack.association.gnn import GNNAssigner
from skytrack.association.identity_scorer import IDENTITY_RULES, IdentityRuleScorer
from skytrack.association.scoring import LikelihoodRatioScorer, LogLikelihoodScorer, MahalanobisScorer

#: "nn" is spec 003's name of the coordinate-only rule, the Mahalanobis scorer "d2"
SCORERS = {"d2": MahalanobisScorer, "nn": MahalanobisScorer, "loglik": LogLikelihoodScorer,
           "llr": LikelihoodRatioScorer, **{rule: partial(IdentityRuleScorer, rule=rule) for rule in IDENTITY_RULES}}
ASSIGNERS = {"gnn": GNNAssigner}


def build_scorer(name: str, **options):
    if name not in SCORERS:
        raise ValueError(f"unknown scorer {name!r}; registered: {', '.join(sorted(SCORERS))}")
    return SCORERS[name](**options)


def build_assigner(name: str, **options):
    if name not in ASSIGNERS:
        raise ValueError(f"unknown assigner {name!r}; registered: {', '.join(sorted(ASSIGNERS))}")
    return ASSIGNERS[name](**options)

"""The actors' former module path, kept because run configs name it.

``config.json`` of runs trained before the networks moved to :mod:`frbench.networks.models` (and the shipped
checkpoints' ``config_json``) give ``frbench.training.models:EstimatorActor`` / ``:RMAActor`` as the actor's
``class_name``; rsl-rl resolves that string when such a run is resumed. New runs name
:mod:`frbench.networks.models`.
"""

from frbench.networks.models import AdaptationModule, EstimatorActor, RMAActor

__all__ = ["AdaptationModule", "EstimatorActor", "RMAActor"]

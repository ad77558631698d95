"""``scripted``: placeholder until the model-based controller lands (holds the default pose)."""

from frbench.policies.zero import ZeroPolicy


class ScriptedPolicy(ZeroPolicy):
    name = "scripted"

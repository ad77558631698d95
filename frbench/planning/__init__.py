"""Sampling-based model-predictive planning on a MuJoCo copy of the episode (the `mpc` policy): model, cost, sampler, config."""

"""The networks of the learned policies (rsl-rl models and FR-Net's estimator): what training builds and
evaluation loads, below both."""

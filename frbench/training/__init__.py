"""FR-Net training: rewards, domain randomisation and the terrain curriculum."""

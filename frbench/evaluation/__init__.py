"""``frbench evaluate``: run a policy over a grid of cells and write a results JSON."""

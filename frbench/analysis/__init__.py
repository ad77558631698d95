"""Analyses of trained policies (the Mass-Contact Predictor's quality)."""

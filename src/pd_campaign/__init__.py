"""Experiment campaign of pedicle_drilling: design, trial execution, statistics and report."""

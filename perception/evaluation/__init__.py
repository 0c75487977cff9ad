"""Evaluation of the perception core against ground truth (tracking, foreground) and the synthetic
scenes and pictures that tests and benchmarks measure it on. Not used by the daemon."""

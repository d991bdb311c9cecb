"""Visualisation of esp_gym runs: matplotlib figures (:mod:`esp_gym.viz.figures`)."""

"""Benchmarks of esp_gym, each run from the repository root as ``python -m benchmarks.NAME``
(``--help`` for its options, ``--quick`` for a smoke run); shared pieces in
:mod:`benchmarks.common`."""

"""Measuring the solver: simulated cases with known truth, their scoring, speed against accuracy.

Not part of the product (:mod:`solver` never imports it): the accuracy tests,
``python -m measurement.validation``, ``tactile-tradeoff``, the viewer's
quality presets and the benchmarks use it. numpy and scipy only: no Qt, no
pyvista, not the viewer.

- :mod:`measurement.cases`: the one :class:`~measurement.cases.Case` and every set of them;
- :mod:`measurement.validation`: accuracy (scoring, the mismatch of kernels and media);
- :mod:`measurement.tradeoff`: speed against accuracy of :data:`solver.quality.CONFIGURATIONS`;
- :mod:`measurement.tables`: the one plain-text table formatter;
- :mod:`measurement.bench`: the solver's timings (``python -m measurement.bench``);
- :mod:`measurement.timing`: how a timing is taken, and the machine line.
"""

"""Figures and the self-contained HTML report.

* :mod:`.static_plots` -- Allan deviation figures;
* :mod:`.dynamic_plots` -- dynamic intervals, trajectory and comparison figures;
* :mod:`.html` -- the HTML report of a results directory.
"""

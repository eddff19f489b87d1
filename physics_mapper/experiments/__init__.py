"""The paper's experiments (Wagle & Correll 2010, section IV), reproduced as plots and summaries (ROS-free).

One module per figure (``fig4``, ``fig6``, ``fig8``, ``peg``), each with ``run(options) ->
ExperimentOutput``; ``common`` holds the options, error metric, plotting and output helpers,
``tracking`` the particle-filter-and-search loop of Figs. 6 and 8. matplotlib (Agg).
Run them with ``physics-mapper experiment {fig4,fig6,fig8,peg,all}`` or ``make paper``.
"""

from __future__ import annotations

from physics_mapper.experiments.common import ExperimentOptions, ExperimentOutput

__all__ = ["ExperimentOptions", "ExperimentOutput"]

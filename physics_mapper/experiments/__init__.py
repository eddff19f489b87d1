"""The paper's experiments (Wagle & Correll 2010, section IV), reproduced as plots and summaries (ROS-free).

One module per figure (``fig4``, ``fig6``, ``fig8``, ``peg``), each with ``run(options) ->
ReportFiles``; ``common`` holds the options, error metric and plotting helpers (statistics and
outputs are :mod:`physics_mapper.evaluation`'s),
``tracking`` the particle-filter-and-search loop of Figs. 6 and 8. matplotlib (Agg).
Run them with ``physics-mapper experiment {fig4,fig6,fig8,peg,all}`` or ``make paper``.
"""

"""Offline evaluation of recorded data (ROS-free): search the snapshots of bags, score them, report.

``snapshots`` cuts a bag into the node's input snapshots; ``snapshot_results`` searches them as the node
would and ``scoring`` measures an estimate against ground truth; for many bags at once
(``evaluate``, ``sweep``) ``sources`` surveys the bags, ``settings`` turns ``--set``/``--grid``
into search parameters, ``tasks`` is one bag as a worker runs it, ``executors`` runs tasks here,
on a process pool or on Ray, ``runner`` drives a run and ``progress`` shows it; ``summary`` and
``statistics`` compute the figures, ``reports``, ``plots`` and ``outputs`` write them.
"""

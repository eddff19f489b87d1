"""The searches over configurations (ROS-free): the paper's Algorithm 1 and what scales it.

``results`` holds what a search returns (codes, trace entries, statistics, the result);
``branch_and_bound`` is Algorithm 1, the best-first branch and bound; ``groups`` splits a scene
into interaction groups; ``grouped`` runs Algorithm 1 per group under one deadline;
``conflict_directed`` is the default search, per group: it learns ``conflicts`` from each rejection
(collisions, and the blame rule for instabilities), rules ranks out before a group's first
candidate (``ruling_out``), checks Rule 2 of what changed and its neighbours (``local_settling``)
and queues an expansion's children once the best-first order could need them
(``pending_children``); ``strategy`` picks the search that ``strategy:`` names; ``report`` turns
results into JSON and text. Imports ``model`` and ``physics``.
"""

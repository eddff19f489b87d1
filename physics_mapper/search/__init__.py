"""The searches over configurations (ROS-free): the paper's Algorithm 1 and what scales it.

``results`` holds what a search returns (codes, trace entries, statistics, the result);
``branch_and_bound`` is Algorithm 1, the best-first branch and bound; ``groups`` splits a scene
into interaction groups; ``grouped`` runs Algorithm 1 per group under one deadline; ``strategy``
picks the search that ``strategy:`` names; ``report`` turns results into JSON and text.
Imports ``model`` and ``physics``.
"""

"""The searches over configurations (ROS-free): the paper's Algorithm 1 and what scales it.

``results`` holds what a search returns (codes, trace entries, statistics, the result);
``best_first`` is the one best-first core (Algorithm 1's loop, bound, tie rule, trace, anytime
result), to which its parts are passed: a candidate generator (``paper_queue``, the paper's queue of
children; ``conflict_directed``, conflict-free generation (``conflict_free``) that learns
``conflicts`` from each rejection and rules ranks out before the first candidate (``ruling_out``)),
a Rule 1 check (``rule1``), a Rule 2 policy (``rule2``: full and memoised settling;
``trial_settling``: trial settlings of what changed and its neighbours, ``local_settling``);
``groups`` splits a scene into interaction groups and ``grouped`` schedules one core per group under
one deadline; ``strategy`` composes each ``strategy:`` from these parts, in one table; ``report``
turns results into JSON and text. Imports ``model`` and ``physics``.
"""

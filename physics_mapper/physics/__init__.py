"""The paper's two rigid-body rules, checked in pybullet (ROS-free).

``world`` builds one persistent pybullet world from a scene and poses its bodies; ``collision`` is
Rule 1 (no overlap deeper than ``penetration_threshold``, metres); ``settling`` is Rule 2 (jitter
under gravity for ``settle_time`` seconds, resumable across deadlines); ``checker`` puts the
three behind :class:`~physics_mapper.physics.checker.PhysicsChecker`. ``collision_table`` caches
Rule 1 per pair of hypotheses; ``refine`` makes a map when no configuration is valid
(``fallback: refine``), of the objects ``support`` keeps. Imports only ``model``.
"""

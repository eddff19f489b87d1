"""The subcommands of ``physics-mapper`` (:mod:`physics_mapper.cli`), one module each; shared helpers in ``files``.

This package imports nothing heavy: the node's entry point (:func:`physics_mapper.commands.node.main`)
must run its first line before numpy starts threads (see ``hold_stop_signals``).
"""

"""The child process a decomposition runs in: ``python -m physics_mapper.model.decomposition_worker FOLDER``.

CoACD and V-HACD are native code: while they run, Python handles no signal, and nothing bounds
their time or memory (V-HACD on a thin plate ran for over 500 s, past 19 GB). So each runs here,
in a process of its own, which limits its own address space and CPU time (``resource.setrlimit``)
before it loads either library; the parent (:func:`~physics_mapper.model.decomposition.decompose`)
waits for it with a wall-clock limit, and kills it at once when it is interrupted (SIGINT, SIGTERM)
or past its limit.

``FOLDER`` holds ``request.json`` (method, threshold, limits) and ``mesh.npz`` (``vertices``,
``faces``); the child writes ``parts.npz`` (``v0``, ``f0``, ``v1``, ...) there, or
``error.txt`` with one line, and exits 0, or non-zero on a failure it could not report. V-HACD's own files
go there too: the parent removes the folder, also after killing the child.
"""

from __future__ import annotations

import json
import resource
import sys
from pathlib import Path
from typing import Any

#: Exit status of a child that reported its own failure in ``error.txt``.
EXIT_REPORTED = 3


def limit_resources(memory_bytes: int, cpu_seconds: int) -> None:
    """Cap this process's address space and CPU time (hard limits stay: the child cannot raise them)."""
    resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))
    resource.setrlimit(resource.RLIMIT_CPU, (cpu_seconds, cpu_seconds + 5))


def main(folder: Path) -> int:
    request = json.loads((folder / "request.json").read_text(encoding="utf-8"))
    limit_resources(int(request["memory_bytes"]), int(request["cpu_seconds"]))
    import numpy as np

    from physics_mapper.model.decomposition import DecompositionError, DecompositionSettings, run_method

    try:
        with np.load(folder / "mesh.npz") as mesh:
            vertices, faces = mesh["vertices"], mesh["faces"]
        settings = DecompositionSettings(request["method"], float(request["threshold"]))
        parts = run_method(vertices, faces, settings, folder)
    except (DecompositionError, MemoryError) as error:
        reason = "out of memory" if isinstance(error, MemoryError) else str(error)
        (folder / "error.txt").write_text(" ".join(reason.split()) + "\n", encoding="utf-8")
        return EXIT_REPORTED
    arrays: dict[str, Any] = {}
    for index, part in enumerate(parts):
        arrays[f"v{index}"], arrays[f"f{index}"] = part.vertices, part.faces
    np.savez(folder / "parts.npz", allow_pickle=False, **arrays)
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))

"""Input notes quote input clipped: a thousand unknown class ids of 100 kB each are logged and remembered
as lines of at most ``MAX_INPUT_NOTE_TEXT`` characters, escaped, never whole.

The logger here records what the node would log (the notes decide what to log; rclpy's logger only
prints it)."""

from __future__ import annotations

from typing import Any

from physics_mapper.ros.node_inputs import MAX_INPUT_NOTE_TEXT, MAX_LOGGED_INPUT_NOTES, InputNotes


class Recorder:
    """Lines given to ``warning``, as rclpy's logger would print them."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def warning(self, text: str, **options: Any) -> None:
        self.lines.append(text)


def test_unknown_class_ids_are_logged_clipped_and_escaped() -> None:
    recorder = Recorder()
    notes = InputNotes(recorder)
    for index in range(MAX_LOGGED_INPUT_NOTES + 100):
        class_id = f"{index}\x1b[31m\n" + "x" * 100_000
        notes.log_once("/detections", f"class id {class_id!r} is no object of the scene")
    assert len(recorder.lines) == MAX_LOGGED_INPUT_NOTES + 100
    longest = max(len(line) for line in recorder.lines)
    assert longest <= len("/detections: ") + MAX_INPUT_NOTE_TEXT, longest
    assert all("\x1b" not in line and "\n" not in line for line in recorder.lines)
    assert "characters)" in recorder.lines[0]  # says how long the note was

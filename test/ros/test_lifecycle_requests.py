"""Bad lifecycle requests get a failed response and a log line, never an exit: transitions by an id the
current state has none for (activate while unconfigured, configure after finalized), unknown labels."""

from __future__ import annotations

from pathlib import Path

from conftest import SCENES
from lifecycle_msgs.msg import State, Transition
from lifecycle_msgs.srv import ChangeState, GetState
from ros_helpers import REPLY_TIMEOUT, STARTUP_TIMEOUT, NodeProcess, RosClient, node_full_name

NAMESPACE = "/lifecycle_requests"


def test_unregistered_transition_ids_and_labels_are_refused_and_logged(tmp_path: Path) -> None:
    node = NodeProcess(SCENES / "pyramid.yaml", {}, tmp_path / "node.log", NAMESPACE, managed=True)
    client = RosClient(NAMESPACE)
    try:
        name = node_full_name(NAMESPACE)
        change = client.node.create_client(ChangeState, f"{name}/change_state")
        get = client.node.create_client(GetState, f"{name}/get_state")
        client.wait_for(lambda: change.service_is_ready() and get.service_is_ready(), STARTUP_TIMEOUT, "services")

        def request(transition: Transition) -> bool:
            future = change.call_async(ChangeState.Request(transition=transition))
            client.wait_for(future.done, REPLY_TIMEOUT, f"change_state {transition}")
            return bool(future.result().success)  # type: ignore[no-untyped-call]

        def state() -> int:
            future = get.call_async(GetState.Request())
            client.wait_for(future.done, REPLY_TIMEOUT, "get_state")
            return int(future.result().current_state.id)  # type: ignore[no-untyped-call]

        # A service's first answer may be lost (RosClient.answered): ask the state, which changes nothing, first.
        client.answered(lambda: get.call_async(GetState.Request()), "get_state")
        assert not request(Transition(id=Transition.TRANSITION_ACTIVATE))  # while unconfigured
        assert not request(Transition(id=250))  # no transition has it
        assert not request(Transition(label="fly\naway"))
        assert node.alive and state() == State.PRIMARY_STATE_UNCONFIGURED
        assert request(Transition(id=Transition.TRANSITION_CONFIGURE))
        assert request(Transition(id=Transition.TRANSITION_INACTIVE_SHUTDOWN))
        assert not request(Transition(id=Transition.TRANSITION_CONFIGURE))  # after finalized
        assert node.alive and state() == State.PRIMARY_STATE_FINALIZED
    finally:
        client.close()
        code = node.stop()
    log = node.output()
    assert code == 0 and "Traceback" not in log, log
    refused = [line for line in log.splitlines() if "physics_mapper]: lifecycle transition" in line]
    assert len(refused) == 4 and all("Transition is not registered" in line for line in refused[:2]), log
    assert "lifecycle transition 3 refused" in refused[0] and "lifecycle transition 250 refused" in refused[1]
    assert "lifecycle transition 1 refused: " in refused[3]
    assert "lifecycle transition 'fly\\naway' not done" in log

"""The conflict-free generator against brute force: exactly the configurations holding no known conflict,
in the paper's order (p(C) rounded to 12 digits, then the smaller code), under the bound."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

from hypothesis import given, settings
from hypothesis import strategies as st

from physics_mapper.search.best_first import tie_key
from physics_mapper.search.conflict_free import ConflictFreeCandidates
from physics_mapper.search.conflicts import Conflict, ConflictStore
from physics_mapper.search.results import Code

#: Weights drawn from few values, so that many products tie (the tie rule then decides).
WEIGHTS = st.sampled_from((0.05, 0.1, 0.2, 0.25, 0.3, 0.5))


@st.composite
def groups(draw: st.DrawFn) -> tuple[list[list[float]], list[Conflict]]:
    """Per object (N <= 6) its weights by rank (M <= 4, non-increasing), and random conflicts with rank sets."""
    count = draw(st.integers(1, 6))
    weights = [sorted(draw(st.lists(WEIGHTS, min_size=1, max_size=4)), reverse=True) for _ in range(count)]
    conflicts = []
    for _ in range(draw(st.integers(0, 16))):
        positions = sorted(draw(st.sets(st.integers(0, count - 1), min_size=1, max_size=min(3, count))))
        ranks = [frozenset(draw(st.sets(st.integers(1, len(weights[p])), min_size=1))) for p in positions]
        own = [draw(st.sampled_from(sorted(r))) for r in ranks]
        conflicts.append(Conflict(tuple(zip(positions, own, strict=True)), "collision", ranks=tuple(ranks)))
    return weights, conflicts


def probability(weights: list[list[float]], code: Code) -> float:
    return math.prod(w[rank - 1] for w, rank in zip(weights, code, strict=True))


def paper_order(weights: list[list[float]]) -> list[Code]:
    """Every configuration, in the paper's order."""
    codes = itertools.product(*(range(1, len(w) + 1) for w in weights))
    return sorted(codes, key=lambda code: (-tie_key(probability(weights, code)), code))


def parents_above(weights: list[list[float]], code: Code, bounded: Callable[[float], bool]) -> bool:
    """Whether ``code`` has no parent or one above the bound."""
    parents = [(*code[:p], r - 1, *code[p + 1 :]) for p, r in enumerate(code) if r > 1]
    return not parents or any(not bounded(probability(weights, parent)) for parent in parents)


def generated(
    weights: list[list[float]], store: ConflictStore, bounded: Callable[[float], bool] = lambda _: False
) -> list[tuple[Code, float]]:
    candidates = ConflictFreeCandidates(weights, store, bounded, queue_limit=1_000_000)
    found = []
    while (next_one := candidates.take()) is not None:
        found.append(next_one)
    return found


# A thousand groups: a bound that prices one object twice (two conflicts sharing it) puts candidates out
# of order in a few of them only.
@settings(max_examples=1_000)
@given(groups())
def test_the_generator_yields_exactly_the_conflict_free_configurations_in_the_papers_order(
    group: tuple[list[list[float]], list[Conflict]],
) -> None:
    weights, conflicts = group
    store = ConflictStore([len(w) for w in weights])
    for conflict in conflicts:
        store.learn(conflict)
    expected = [code for code in paper_order(weights) if not any(c.holds_in(code) for c in conflicts)]
    found = generated(weights, store)
    assert [code for code, _ in found] == expected
    assert all(p == probability(weights, code) for code, p in found)  # the search's own product, bit for bit


@given(groups(), st.floats(0.0, 0.2))
def test_under_the_bound_only_configurations_with_a_parent_above_it_are_generated(
    group: tuple[list[list[float]], list[Conflict]], threshold: float
) -> None:
    weights, conflicts = group
    store = ConflictStore([len(w) for w in weights])
    for conflict in conflicts:
        store.learn(conflict)

    def bounded(p: float) -> bool:
        return p < threshold

    expected = [
        code
        for code in paper_order(weights)
        if not any(c.holds_in(code) for c in conflicts) and parents_above(weights, code, bounded)
    ]
    assert [code for code, _ in generated(weights, store, bounded)] == expected


@given(groups(), st.data())
def test_conflicts_learned_between_candidates_apply_to_every_later_one(
    group: tuple[list[list[float]], list[Conflict]], data: st.DataObject
) -> None:
    """Conflicts learned one at a time while candidates are taken: each candidate is the first, after the
    last one taken, in the paper's order, of the configurations holding no conflict known by then."""
    weights, conflicts = group
    store = ConflictStore([len(w) for w in weights])
    candidates = ConflictFreeCandidates(weights, store, lambda _: False, queue_limit=1_000_000)
    order = paper_order(weights)
    place = {code: index for index, code in enumerate(order)}
    last = -1
    pending = list(conflicts)
    while True:
        if data.draw(st.booleans()) and pending:
            store.learn(pending.pop(0))
        if data.draw(st.booleans()):
            candidates.find()  # found before conflicts are learned, taken after
            if pending:
                store.learn(pending.pop(0))
        known = list(store)
        wanted = next((code for code in order[last + 1 :] if not any(c.holds_in(code) for c in known)), None)
        taken = candidates.take()
        assert (None if taken is None else taken[0]) == wanted
        if taken is None:
            break
        last = place[taken[0]]


def test_a_configuration_outside_a_conflict_s_rank_sets_comes_in_its_place() -> None:
    """Object 0 at rank 1 or 2 leaves object 1 only its poor rank 2 (one conflict, a rank set), at rank 3
    its best: C31 (p = 0.27) comes first, before C12 and C22 with object 0's better weights."""
    weights = [[0.4, 0.35, 0.3], [0.9, 0.1]]
    store = ConflictStore([3, 2])
    store.learn(Conflict(((0, 1), (1, 1)), "collision", ranks=(frozenset({1, 2}), frozenset({1}))))
    assert [code for code, _ in generated(weights, store)] == [(3, 1), (1, 2), (2, 2), (3, 2)]


def test_a_region_is_split_on_the_conflict_that_costs_most_to_leave() -> None:
    """The root C111 holds two conflicts of two objects: object 1 with object 2 (learned first; object 1 leaves it
    for 2.5 times less p(C)) and object 0 with object 2 (3 times less, object 2 leaving). Split on the costlier,
    the generator takes up 6 regions before the first candidate, C212; on the first learned it took up 9."""
    weights = [[0.6, 0.1], [0.5, 0.2], [0.6, 0.2]]
    store = ConflictStore([2, 2, 2])
    for assignments in (((0, 1), (2, 2)), ((0, 2), (2, 1)), ((1, 1), (2, 1)), ((0, 1), (2, 1))):
        store.learn(Conflict(assignments, "collision"))
    candidates = ConflictFreeCandidates(weights, store, lambda _: False, queue_limit=1_000)
    first = candidates.take()
    assert first is not None
    expected = next(code for code in paper_order(weights) if not any(c.holds_in(code) for c in store))
    assert first[0] == expected == (2, 1, 2)
    assert candidates.taken_up == 6

"""Stays: the maximal runs of samples with the token in one place, from a tag per sample."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from multiform.learn.views import stays, token_place
from multiform.petri.skillfile import load_skill

APN = load_skill("pendulum")
TAGS = st.lists(st.sampled_from(["", "t0", "t1", "t2", "t3", "t5", "not_a_transition"]), max_size=60)


@settings(max_examples=300, deadline=None)
@given(TAGS)
def test_stays_are_the_maximal_runs_of_one_place(tags):
    place = [token_place(APN, t) if t else None for t in tags]
    got = stays(APN, tags)
    assert got == stays(APN, np.array(tags, dtype=object))
    covered = [None] * len(tags)
    end = 0
    for s, e, p in got:
        assert end <= s < e <= len(tags)                      # in order, disjoint, not empty
        assert all(q == p for q in place[s:e])
        assert s == 0 or place[s - 1] != p                    # maximal on both sides
        assert e == len(tags) or place[e] != p
        covered[s:e] = [p] * (e - s)
        end = e
    assert covered == place                                   # every sample with a place is in one


def test_repeats_and_a_catch_join_their_places():
    # t2 repeats the swing-up in P1, t3 the balancing in P2: one stay each, whatever the maneuver
    assert stays(APN, ["t0", "t0", "t2", "t1", "t3", "", "t5"]) == [(0, 3, "P1"), (3, 5, "P2"), (6, 7, "fail")]

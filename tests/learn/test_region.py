"""Place regions: calibrated membership, the best-matching place, and "no place relates"."""

import numpy as np
import pytest

from multiform.errors import InvalidInput
from multiform.io import load_npz, save_npz
from multiform.learn.condition import load_condition
from multiform.learn.region import KIND, VERSION, PlaceRegions, RegionCondition, share_regions
from multiform.petri.firing import NetRunner
from multiform.petri.revision import add_transition
from multiform.petri.skillfile import load_skill

from .synthetic import place_states

NAMES = ("theta", "omega")
DISTURBED = np.array([0.6, 3.0])          # pushed off upright: looks like a swing, not balancing
UPRIGHT = np.array([0.02, 0.1])
FAR = np.array([0.0, 15.0])               # spinning faster than any demonstration


@pytest.fixture(scope="module")
def regions():
    return PlaceRegions(NAMES).fit(place_states(0, n=1500))


def test_coverage_on_held_out_states(regions):
    cov = regions.coverage_on(place_states(1, n=1500))
    print(f"\nheld-out coverage (target {regions.coverage:.0%}): {cov}; components {regions.components_}")
    for p in ("P1", "P2"):
        assert cov[p] >= 0.94


def test_best_place_and_no_place(regions):
    assert regions.best(np.stack([DISTURBED, UPRIGHT, FAR])) == ["P1", "P2", None]
    s = regions.scores(DISTURBED)
    assert s["P1"][0] >= 0.5 > s["P2"][0]
    s = regions.scores(FAR)
    assert max(v[0] for v in s.values()) < 0.05
    # states of the other place mostly fall outside a place's region
    other = place_states(2, n=1500)
    assert regions.belongs(other["P2"], "P2").mean() > 0.9
    assert regions.scores(other["P1"])["P2"].mean() < 0.2


def test_fast_path_equals_vectorised(regions):
    X = np.concatenate([place_states(3, n=200)["P1"], place_states(3, n=200)["P2"], [DISTURBED, FAR]])
    s = regions.scores(X)
    for p in regions.places_:
        one = np.array([regions.score_one(x, p) for x in X])
        np.testing.assert_allclose(one, s[p], rtol=1e-10, atol=1e-12)


def test_conditions_for_the_repair_loop(regions, tmp_path):
    back = regions.condition("P1", rather_than="P2")                  # the paper's t7: P2 -> P1
    assert back(DISTURBED) and not back(UPRIGHT) and not back(FAR)
    # Never while the state is still in P2's region, even where P1 scores higher (a catch just
    # begun): a way back that held there would undo every entry into P2 at once.
    p2 = place_states(5, n=400)["P2"]
    inside_p2 = regions.belongs(p2, "P2")
    assert inside_p2.mean() > 0.9 and not back.holds(p2[inside_p2]).any()
    out = regions.outside_condition()
    assert out(FAR) and not out(DISTURBED) and not out(UPRIGHT)
    X = np.concatenate([place_states(4, n=300)["P1"], [DISTURBED, UPRIGHT, FAR]])
    np.testing.assert_array_equal(back.holds(X), [back(x) for x in X])
    np.testing.assert_array_equal(out.holds(X), [out(x) for x in X])

    # With a floor below the boundary the way back waits until the state is further out.
    deep = regions.condition("P1", rather_than="P2", leave_below=-3.0)
    z2 = regions.logits(X)[:, regions.places_.index("P2")]
    np.testing.assert_array_equal(deep.holds(X), back.holds(X) & (z2 < -3.0))
    deep.save(tmp_path / "deep.npz")
    again = load_condition(tmp_path / "deep.npz", input_names=NAMES)
    assert again.leave_below == -3.0
    np.testing.assert_array_equal(again.holds(X), deep.holds(X))
    with pytest.raises(ValueError):
        regions.condition("P1", rather_than="P2", leave_below=0.5)

    # "outside" leaving P2: P2 must be below its floor, every other place below its boundary
    out_deep = regions.outside_condition("P2", leave_below=-3.0)
    Z = regions.logits(X)
    np.testing.assert_array_equal(out_deep.holds(X), (Z[:, regions.places_.index("P1")] < 0) & (z2 < -3.0))
    np.testing.assert_array_equal(out_deep.holds(X), [out_deep(x) for x in X])
    out_deep.save(tmp_path / "out.npz")
    np.testing.assert_array_equal(load_condition(tmp_path / "out.npz", input_names=NAMES).holds(X), out_deep.holds(X))

    path = tmp_path / "t7.npz"
    back.save(path)
    again = load_condition(path, input_names=NAMES)
    assert isinstance(again, RegionCondition) and again.into == "P1" and again.rather_than == "P2"
    np.testing.assert_array_equal(again.holds(X), back.holds(X))


def test_t7_back_to_swung_up_in_the_net(regions):
    """The paper's repair: a transition from "balanced" back to "swung up" that fires when a push
    has thrown the state into the swing-up region."""
    apn, _ = add_transition(load_skill("pendulum"), "t7", {"in": ["P2"], "out": ["P1"], "law": "swing_up",
                                                            "condition": {"model": "t7"}}, "test")
    runner = NetRunner(apn, ["theta", "omega", "x", "xdot"], learned={"t7": regions.condition("P1", "P2")}, rng=0)
    assert runner.tick([np.pi, 0.0, 0.0, 0.0], 0.0) == ["t0"]
    assert runner.tick([0.02, 0.1, 0.0, 0.0], 0.1) == ["t1"]          # balanced
    assert runner.tick([0.01, -0.2, 0.0, 0.0], 0.2) == []              # still balanced: t7 quiet
    assert runner.tick([0.6, 3.0, 0.0, 0.0], 0.3) == ["t7"]            # pushed: back to swing-up


def test_save_load_round_trip_and_bad_files(regions, tmp_path):
    path = tmp_path / "regions.npz"
    regions.save(path)
    back = PlaceRegions.load(path, input_names=NAMES)
    X = place_states(5, n=300)["P1"]
    for p in regions.places_:
        np.testing.assert_array_equal(back.scores(X)[p], regions.scores(X)[p])
    good = path.read_bytes()
    with pytest.raises(InvalidInput, match="input_names"):
        PlaceRegions.load(path, input_names=("s", "c", "omega"))

    arrays, meta = load_npz(path, KIND, VERSION)
    bad = tmp_path / "bad.npz"
    save_npz(bad, {**arrays, "p0_means": arrays["p0_means"][:, :1]}, meta, KIND, VERSION)
    with pytest.raises(InvalidInput, match="p0_means") as e:
        PlaceRegions.load(bad)
    assert "bad.npz" in str(e.value)
    save_npz(bad, arrays, {**meta, "places": ["P1"]}, KIND, VERSION)
    with pytest.raises(InvalidInput, match="densities"):
        PlaceRegions.load(bad)
    with pytest.raises(InvalidInput, match="expected a 'region_condition'"):
        RegionCondition.load(path)
    path.write_bytes(good[:-40])
    with pytest.raises(InvalidInput, match="regions.npz"):
        PlaceRegions.load(path)
    assert path.read_bytes() == good[:-40]


def test_too_few_states():
    with pytest.raises(ValueError, match="too few"):
        PlaceRegions(NAMES).fit({"P1": np.zeros((5, 2))})


def test_conditions_on_the_same_regions_share_one_scoring(regions, tmp_path):
    """A way back and an "outside" condition from the same place score each state once; the memo
    of the last state never answers for another state."""
    back, out = regions.condition("P1", "P2"), regions.outside_condition("P2", leave_below=-3.0)
    other = regions.condition("P1")                    # P1 only: different regions, not shared
    for name, c in (("back", back), ("out", out), ("other", other)):
        c.save(tmp_path / f"{name}.npz")
    conds = {n: load_condition(tmp_path / f"{n}.npz", input_names=NAMES) for n in ("back", "out", "other")}
    share_regions(conds)
    assert conds["back"].regions is conds["out"].regions is not conds["other"].regions
    X = np.concatenate([place_states(6, n=200)["P1"], place_states(6, n=200)["P2"], [DISTURBED, UPRIGHT, FAR]])
    buf = np.empty(len(NAMES))                         # one buffer, refilled each tick: as the net's guards do
    got = {n: [] for n in conds}
    for x in X:
        buf[:] = x
        for n, c in conds.items():
            got[n].append(c(buf))
    for n, ref in (("back", back), ("out", out), ("other", other)):
        np.testing.assert_array_equal(got[n], ref.holds(X))

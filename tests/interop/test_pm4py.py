"""PNML both ways with pm4py: pm4py reads our exports (weights, final marking); nets pm4py builds
and mines import and pass `multiform check`."""

import warnings

import pandas as pd
import pm4py
import pytest
from pm4py.objects.petri_net.obj import Marking, PetriNet
from pm4py.objects.petri_net.utils import petri_utils

from multiform.cli import main
from multiform.petri.pnml import read_pnml, write_pnml
from multiform.petri.revision import add_transition
from multiform.petri.skill_schema import IDENT
from multiform.petri.skillfile import load_skill


def _log() -> pd.DataFrame:
    rows = []
    traces = [["start", "a", "b", "c", "d"], ["start", "a", "c", "b", "d"], ["start", "a", "e", "d"]]
    for case, trace in enumerate(traces * 2):
        for i, act in enumerate(trace):
            rows.append({"case:concept:name": str(case), "concept:name": act,
                         "time:timestamp": pd.Timestamp("2026-01-01") + pd.Timedelta(minutes=10 * case + i)})
    return pd.DataFrame(rows)


def _constructed():
    net = PetriNet("hand built")
    start, mid, end = PetriNet.Place("start"), PetriNet.Place("mid"), PetriNet.Place("end")
    for p in (start, mid, end):
        net.places.add(p)
    go, tau = PetriNet.Transition("t1", "go"), PetriNet.Transition("t 2", None)
    net.transitions.update({go, tau})
    petri_utils.add_arc_from_to(start, go, net)
    petri_utils.add_arc_from_to(go, mid, net, weight=2)
    petri_utils.add_arc_from_to(mid, tau, net, weight=2)
    petri_utils.add_arc_from_to(tau, end, net)
    return net, Marking({start: 1}), Marking({end: 1})


def _pm4py_read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from pm4py.objects.petri_net.importer.variants import pnml
        return pnml.import_net(str(path), parameters={"return_stochastic_map": True})


def test_pm4py_reads_weights_and_final_marking(tmp_path):
    apn, _ = add_transition(load_skill("pendulum"), "t7", {"in": {"P2": 2}, "out": ["P1"], "law": "swing_up",
                                                             "lambda": 0.25}, "x")
    path = tmp_path / "net.pnml"
    write_pnml(apn, path)
    net, im, fm, stochastic = _pm4py_read(path)
    assert {t.name: rv.get_weight() for t, rv in stochastic.items()} == {t.id: t.lam for t in apn.transitions}
    assert {p.name: n for p, n in fm.items()} == {p: 1 for p, k in apn.final_places.items() if k == "success"}
    assert {p.name: n for p, n in im.items()} == dict(apn.initial_marking)
    assert {(a.source.name, a.target.name): a.weight for a in net.arcs}[("P2", "t7")] == 2
    assert read_pnml(path) == apn                    # and our own reader still restores everything


@pytest.mark.parametrize("make", ["constructed", "inductive", "alpha"])
def test_pm4py_nets_import_and_pass_check(tmp_path, make, capsys):
    if make == "constructed":
        net, im, fm = _constructed()
    elif make == "inductive":
        net, im, fm = pm4py.discover_petri_net_inductive(_log())
    else:
        net, im, fm = pm4py.discover_petri_net_alpha(_log())
    path = tmp_path / f"{make}.pnml"
    pm4py.write_pnml(net, im, fm, str(path))
    out = tmp_path / f"{make}.yaml"
    assert main(["net", "import", str(path), "-o", str(out)]) == 0
    assert main(["check", str(out)]) == 0, capsys.readouterr()
    apn = read_pnml(path)
    assert all(IDENT.match(x) for x in apn.place_ids + apn.transition_ids)
    assert len(apn.places) == len(net.places) and len(apn.transitions) == len(net.transitions)
    final_names = {p.name for p in fm}
    finals = {p.label or p.id for p in apn.places if p.final == "success"}
    assert finals == final_names
    # every original name survives, as the id or as its label
    kept = {p.label or p.id for p in apn.places} | {t.label or t.id for t in apn.transitions}
    assert {p.name for p in net.places} <= kept
    assert {t.label for t in net.transitions if t.label} <= kept
    arcs = sorted((a.weight, type(a.source).__name__) for a in net.arcs)
    ours = sorted([(w, "Place") for t in apn.transitions for w in t.inputs.values()]
                  + [(w, "Transition") for t in apn.transitions for w in t.outputs.values()])
    assert ours == arcs


def test_alpha_net_with_a_place_and_transition_sharing_an_id(tmp_path):
    """An activity called 'start' gives pm4py's alpha miner a transition with the id of its source
    place; the arcs say which is meant."""
    net, im, fm = pm4py.discover_petri_net_alpha(_log())
    path = tmp_path / "alpha.pnml"
    pm4py.write_pnml(net, im, fm, str(path))
    assert path.read_text().count('id="start"') == 2
    apn = read_pnml(path)
    start_place = [p for p in apn.places if p.id == "start" or p.label == "start"]
    start_transition = [t for t in apn.transitions if t.id == "start" or t.label == "start"]
    assert len(start_place) == 1 and len(start_transition) == 1
    assert apn.initial_marking == {start_place[0].id: 1}
    assert start_place[0].id in start_transition[0].outputs or any(
        start_place[0].id in t.inputs for t in apn.transitions)


@pytest.mark.parametrize("skill", ["pendulum", "nunchaku"])
def test_export_pm4py_write_import_keeps_the_failure_place_and_passes_check(tmp_path, skill, capsys):
    """pm4py keeps the structure, names and markings but not multiform's block: the dead end that
    was `final: failure` comes back as a failure place, so the net does not deadlock."""
    apn = load_skill(skill)
    assert main(["net", "export", skill, "-o", str(tmp_path / "ours.pnml")]) == 0
    net, im, fm = pm4py.read_pnml(str(tmp_path / "ours.pnml"))
    pm4py.write_pnml(net, im, fm, str(tmp_path / "theirs.pnml"))
    assert "multiform" not in (tmp_path / "theirs.pnml").read_text()
    assert main(["net", "import", str(tmp_path / "theirs.pnml"), "-o", str(tmp_path / "back.yaml")]) == 0
    assert main(["check", str(tmp_path / "back.yaml")]) == 0, capsys.readouterr()
    back = load_skill(tmp_path / "back.yaml")
    assert back.final_places == apn.final_places
    assert sorted(back.place_ids) == sorted(apn.place_ids) and sorted(back.transition_ids) == sorted(apn.transition_ids)
    assert back.name == "theirs"                       # not pm4py's imported_<time>


def test_a_discovered_net_is_named_for_its_file(tmp_path):
    net, im, fm = pm4py.discover_petri_net_inductive(_log())
    assert net.name.startswith("imdf_net_")
    pm4py.write_pnml(net, im, fm, str(tmp_path / "order-handling.pnml"))
    assert read_pnml(tmp_path / "order-handling.pnml").name == "order_handling"

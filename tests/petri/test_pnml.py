import warnings

from hypothesis import given, settings
import pytest
from hypothesis import strategies as st

from multiform.errors import InvalidInput
from multiform.petri.pnml import from_pnml, read_pnml, to_pnml, write_pnml
from multiform.petri.revision import add_transition, set_condition
from multiform.petri.skillfile import load_skill


def _nets():
    apn = load_skill("pendulum")
    apn2, _ = set_condition(apn, "t1", {"model": "t1_learned"}, "x")
    apn3, _ = add_transition(apn2, "t7", {"in": {"P2": 2}, "out": ["P1"], "law": "swing_up", "lambda": 0.25}, "x")
    return [apn, load_skill("pendulum_strict"), apn3]


@pytest.mark.parametrize("apn", _nets(), ids=["pendulum", "strict", "revised"])
def test_round_trip_is_identity(apn):
    back = from_pnml(to_pnml(apn))
    assert back == apn
    for t in apn.transitions:
        b = back.transition(t.id)
        assert (b.lam, str(b.condition), b.law, dict(b.inputs), dict(b.outputs)) == \
               (t.lam, str(t.condition), t.law, dict(t.inputs), dict(t.outputs))


def test_pm4py_reads_the_export(tmp_path):
    pm4py_pnml = pytest.importorskip("pm4py.objects.petri_net.importer.variants.pnml")
    apn = _nets()[2]
    path = tmp_path / "net.pnml"
    write_pnml(apn, path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        net, im, fm, stochastic = pm4py_pnml.import_net(str(path), parameters={"return_stochastic_map": True})
    assert {p.name for p in net.places} == set(apn.place_ids)
    assert {t.name for t in net.transitions} == set(apn.transition_ids)
    arcs = {(a.source.name, a.target.name, a.weight) for a in net.arcs}
    expected = {(p, t.id, w) for t in apn.transitions for p, w in t.inputs.items()} | \
               {(t.id, p, w) for t in apn.transitions for p, w in t.outputs.items()}
    assert arcs == expected
    assert {p.name: n for p, n in im.items()} == dict(apn.initial_marking)
    weights = {t.name: rv.get_weight() for t, rv in stochastic.items()}
    assert weights == {t.id: t.lam for t in apn.transitions}


def test_lenient_reading_without_namespace_or_page():
    text = """<pnml><net id="n" type="ptnet">
      <place id="a"><initialMarking><text>1</text></initialMarking></place>
      <place id="b"><toolspecific tool="multiform" version="1"><place>{"final": "success"}</place></toolspecific></place>
      <transition id="t"/>
      <arc id="x" source="a" target="t"/><arc id="y" source="t" target="b"><inscription><text>2</text></inscription></arc>
    </net></pnml>"""
    apn = from_pnml(text)
    assert apn.transition("t").outputs == {"b": 2}
    assert apn.initial_marking == {"a": 1}
    assert str(apn.transition("t").condition) == "true"


def test_bad_pnml_is_refused(tmp_path):
    with pytest.raises(InvalidInput, match="not well-formed"):
        from_pnml("<pnml><net>", "x.pnml")
    text = to_pnml(load_skill("pendulum")).replace('source="P0" target="t0"', 'source="P0" target="P1"')
    with pytest.raises(InvalidInput, match="connects two places"):
        from_pnml(text, "x.pnml")
    bad = tmp_path / "bad.pnml"
    bad.write_text(to_pnml(load_skill("pendulum")).replace('"condition": "dwell &gt; 2.0"', '"condition": "dwell.x"'))
    with pytest.raises(InvalidInput, match="transitions.t2.condition"):
        read_pnml(bad)


def _pendulum_pnml() -> str:
    return to_pnml(load_skill("pendulum"))


def _with_extra_place(text: str, xml: str) -> str:
    return text.replace("<transition ", xml + "\n<transition ", 1)


@pytest.mark.parametrize("mutate, fragment", [
    (lambda t: _with_extra_place(t, '<place id="P0"><initialMarking><text>3</text></initialMarking></place>'),
     "place P0: duplicate id: a second <place> with id 'P0'"),
    (lambda t: t.replace("</page>", '<transition id="t2"/></page>'),
     "transition t2: duplicate id: a second <transition> with id 't2'"),
    (lambda t: t.replace("<text>1</text>\n        </initialMarking>", f"<text>{2**63}</text></initialMarking>", 1),
     f"place P0: initial marking {2**63} is out of range"),
    (lambda t: t.replace("<inscription>\n          <text>1</text>", "<inscription><text>" + "9" * 4000 + "</text>", 1),
     "inscription a 4000-digit number is out of range"),
    (lambda t: t.replace("<inscription>\n          <text>1</text>", "<inscription><text>-1</text>", 1),
     "inscription '-1' is not a non-negative integer"),
    (lambda t: t.replace('"law": "swing_up"', '"law": ' + "[" * 5000 + "]" * 5000, 1),
     "transition t0: transition data nests 5001 levels deep, more than 32"),
    (lambda t: t.replace('<property key="weight">1.0', '<property key="weight">1' + "0" * 4000, 1),
     "lambda: must be finite"),
    (lambda t: t.replace('"law": "swing_up"', '"law": ' + "9" * 5000, 1),
     "transition t0: transition data is not JSON (Exceeds the limit"),
    (lambda t: t.replace('"condition": "dwell &gt; 2.0"', '"condition": "dwell' + " + dwell" * 200 + '"', 1),
     "transitions.t2.condition: expression nested 201 levels deep, more than 64"),
])
def test_hostile_pnml_refused_by_name(mutate, fragment):
    text = mutate(_pendulum_pnml())
    assert text != _pendulum_pnml()
    with pytest.raises(InvalidInput) as info:
        from_pnml(text, "x.pnml")
    assert fragment in str(info.value)
    assert len(str(info.value)) < 400


def test_huge_counts_in_a_skill_file_refused(tmp_path):
    from multiform.petri.skillfile import parse_skill
    text = load_skill.__globals__["bundled_skills"]()["pendulum"].read_text()
    with pytest.raises(InvalidInput, match=r"initial_marking.P0: token count 9223372036854775808 is out of range"):
        parse_skill(text.replace("P0: 1", f"P0: {2**63}", 1))
    with pytest.raises(InvalidInput, match="nested too deeply"):
        parse_skill(text + "\ndeep: " + "[" * 5000 + "]" * 5000)
    with pytest.raises(InvalidInput, match="Exceeds the limit"):
        parse_skill(text.replace("P0: 1", "P0: " + "9" * 5000, 1))


@pytest.mark.parametrize("encoding", ["iso-8859-1", "utf-16", "windows-1252"])
def test_encoding_declaration_honoured(tmp_path, encoding):
    apn = load_skill("pendulum")
    text = to_pnml(apn).replace('encoding="UTF-8"', f'encoding="{encoding}"')
    text = text.replace(">swung up<", ">swung up, café<")
    path = tmp_path / "latin.pnml"
    path.write_bytes(text.encode(encoding))
    back = read_pnml(path)
    assert back.place("P1").label == apn.place("P1").label
    assert back.transitions == apn.transitions


def test_unknown_encoding_refused(tmp_path):
    path = tmp_path / "x.pnml"
    path.write_bytes(_pendulum_pnml().replace('encoding="UTF-8"', 'encoding="no-such-codec"').encode())
    with pytest.raises(InvalidInput, match="x.pnml: cannot decode the XML"):
        read_pnml(path)


_ID = st.text(st.characters(blacklist_categories=("Cs", "Cc")), min_size=1, max_size=12)


@settings(max_examples=60, deadline=None)
@given(st.lists(_ID, min_size=2, max_size=6, unique=True), st.lists(_ID, min_size=1, max_size=5, unique=True),
       st.randoms(use_true_random=False))
def test_foreign_ids_become_valid_unique_ids_and_keep_the_structure(place_ids, transition_ids, rnd):
    """Any ids another tool writes (spaces, brackets, UUIDs, an id shared by a place and a
    transition) import as valid, unique ids; arcs, weights, marking and names are kept."""
    import xml.etree.ElementTree as ET

    from multiform.petri.skill_schema import IDENT
    root = ET.Element("pnml")
    page = ET.SubElement(ET.SubElement(root, "net", {"id": "n"}), "page", {"id": "p"})
    for i, pid in enumerate(place_ids):
        el = ET.SubElement(page, "place", {"id": pid})
        if i == 0:
            ET.SubElement(ET.SubElement(el, "initialMarking"), "text").text = "1"
    for tid in transition_ids:
        ET.SubElement(page, "transition", {"id": tid})
    arcs = []
    for k, tid in enumerate(transition_ids):             # a chain from the first place to the last
        src, dst = place_ids[min(k, len(place_ids) - 2)], place_ids[-1] if k == len(transition_ids) - 1 else \
            place_ids[min(k + 1, len(place_ids) - 1)]
        w = rnd.randint(1, 3)
        arcs += [(src, tid, 1), (tid, dst, w)]
    for k, (s, t, w) in enumerate(arcs):
        arc = ET.SubElement(page, "arc", {"id": f"a{k}", "source": s, "target": t})
        ET.SubElement(ET.SubElement(arc, "inscription"), "text").text = str(w)
    fm = ET.SubElement(ET.SubElement(ET.SubElement(root[0], "finalmarkings"), "marking"), "place",
                       {"idref": place_ids[-1]})
    ET.SubElement(fm, "text").text = "1"
    try:
        apn = from_pnml(ET.tostring(root))
    except InvalidInput as exc:            # a structurally unsound chain is refused, but never for its ids
        assert "not a valid id" not in str(exc) and "duplicate id" not in str(exc)
        return
    ids = list(apn.place_ids) + list(apn.transition_ids)
    assert all(IDENT.match(x) for x in ids) and len(set(ids)) == len(ids)
    assert len(apn.places) == len(place_ids) and len(apn.transitions) == len(transition_ids)
    assert sorted(w for t in apn.transitions for w in list(t.inputs.values()) + list(t.outputs.values())) == \
        sorted(w for _, _, w in arcs)
    names = {p.label or p.id for p in apn.places}
    assert names == set(place_ids)
    assert apn.final_places == {apn.places[-1].id: "success"} and apn.initial_marking == {apn.places[0].id: 1}

"""Issue #31, class "Destroyed or hidden data" (the layouts): ``adcs-analyze --foxglove-layout`` /
``--plotjuggler-layout`` wrote wherever they were told, over the bag they had just read included.
A layout is never written over the bag, into it, over any input, nor over a file this tool did not
write (a layout of ours of the same kind is recognised from its content and replaced).
"""
from __future__ import annotations

import json
import shutil

import pytest
from support.edge_paths import one_line
from support.paths import ROOT

from adcs_sim.app.graph import layouts
from adcs_sim.app.analysis.analyze import main as analyze

BAG = ROOT / 'bags' / 'microsat_pd_slew' / 'bag'
OPTIONS = {'foxglove': '--foxglove-layout', 'plotjuggler': '--plotjuggler-layout'}


@pytest.fixture
def bag(tmp_path):
    """A copy of a committed bag (the tests try to write over it)."""
    return shutil.copytree(BAG, tmp_path / 'run' / 'bag')


def _files(root):
    return {p: p.read_bytes() for p in root.rglob('*') if p.is_file()}


@pytest.mark.parametrize('viewer', sorted(OPTIONS))
@pytest.mark.parametrize('target', ['mcap', 'metadata', 'new_file_in_bag', 'symlink_to_mcap', 'given_as_mcap'])
def test_a_layout_is_never_written_over_or_into_the_bag(bag, tmp_path, viewer, target, capsys):
    read = bag
    out = {'mcap': bag / 'bag_0.mcap', 'metadata': bag / 'metadata.yaml', 'new_file_in_bag': bag / 'layout.json',
           'symlink_to_mcap': tmp_path / 'layout.json', 'given_as_mcap': bag / 'metadata.yaml'}[target]
    if target == 'symlink_to_mcap':
        out.symlink_to(bag / 'bag_0.mcap')
    if target == 'given_as_mcap':
        read = bag / 'bag_0.mcap'   # the bag named by its file: its folder is still the input
    before = _files(tmp_path)
    assert analyze([str(read), OPTIONS[viewer], str(out)]) == 1
    one_line(capsys.readouterr().err, 'adcs-analyze', out)
    assert _files(tmp_path) == before


@pytest.mark.parametrize('viewer', sorted(OPTIONS))
def test_a_file_that_is_not_our_layout_is_never_overwritten(bag, tmp_path, viewer, capsys):
    others = {'notes.txt': 'my notes\n',
              'foxglove_export.json': json.dumps({'configById': {'Plot!3xyz': {}}, 'layout': 'Plot!3xyz'}),
              'pj_saved.xml': '<root><tabbed_widget name="Main Window"/><Plugins/></root>\n',
              'other_scenario.yaml': (ROOT / 'config' / 'microsat_pd_slew.yaml').read_text()}
    for name, text in others.items():
        (tmp_path / name).write_text(text)
        assert analyze([str(bag), OPTIONS[viewer], str(tmp_path / name)]) == 1
        one_line(capsys.readouterr().err, 'adcs-analyze', tmp_path / name, 'not overwritten')
        assert (tmp_path / name).read_text() == text


def test_our_layout_of_that_kind_is_replaced_and_not_the_other_kind(bag, tmp_path, capsys):
    fox, pj = tmp_path / 'f.json', tmp_path / 'p.xml'
    assert analyze([str(bag), '--foxglove-layout', str(fox), '--plotjuggler-layout', str(pj)]) == 0
    assert layouts.is_foxglove_layout(fox) and layouts.is_plotjuggler_layout(pj)
    assert not layouts.is_foxglove_layout(pj) and not layouts.is_plotjuggler_layout(fox)
    first = fox.read_bytes(), pj.read_bytes()
    assert analyze([str(bag), '--foxglove-layout', str(fox), '--plotjuggler-layout', str(pj)]) == 0
    assert (fox.read_bytes(), pj.read_bytes()) == first
    capsys.readouterr()
    assert analyze([str(bag), '--plotjuggler-layout', str(fox)]) == 1   # a Foxglove layout is no PlotJuggler one
    one_line(capsys.readouterr().err, 'adcs-analyze', fox)
    assert fox.read_bytes() == first[0]


def test_one_path_for_both_layouts_is_refused(bag, tmp_path, capsys):
    out = tmp_path / 'both'
    assert analyze([str(bag), '--foxglove-layout', str(out), '--plotjuggler-layout', str(out)]) == 1
    one_line(capsys.readouterr().err, 'adcs-analyze', out)
    assert not out.exists()


def test_the_reference_file_is_an_input_too(bag, tmp_path, capsys):
    """The layout is refused over every input of the invocation: the ``--reference`` file included."""
    reference = tmp_path / 'paper.yaml'
    reference.write_text('runs: {}\n')
    assert analyze([str(bag), '--reference', str(reference), '--foxglove-layout', str(reference)]) == 1
    one_line(capsys.readouterr().err, 'adcs-analyze', reference)
    assert reference.read_text() == 'runs: {}\n'

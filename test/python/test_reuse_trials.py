"""campaign --reuse-trials (pd_campaign.reuse): a campaign takes the trials a finished campaign
of the same build and engine options ran, and its outputs are those of running them."""
import csv
import filecmp
import json
import os
import subprocess

import pytest

from pd_campaign import reuse

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
SCENARIO = os.path.join(ROOT, 'config', 'scenario_paper.yaml')


def _package(tmp_path):
    root = tmp_path / 'package'
    (root / 'urdf').mkdir(parents=True)
    (root / 'config').mkdir()
    (root / 'urdf' / 'workcell.urdf').write_text('<robot name="a"/>')
    (root / 'config' / 'patient_default.yaml').write_text('a: 1\n')
    (root / 'recognizer_plugins.xml').write_text('<library/>')
    models = tmp_path / 'models'
    models.mkdir()
    (models / 'volunteer_1_linear.yaml').write_text('k: 1\n')
    return root, models


def _command(models, *extra):
    return ['/somewhere/trial_engine', '--trials', '-', '--model', 'linear', '--models-dir',
            str(models)] + list(extra)


def test_the_key_follows_what_a_record_depends_on(tmp_path):
    root, models = _package(tmp_path)
    key = reuse.engine_key(_command(models), str(root), build='b1')
    assert key == reuse.engine_key(_command(models), str(root), build='b1')
    # Not the trials' source, nor the executable's path, nor files trial_engine does not read.
    other = _command(models)
    other[0], other[2] = '/elsewhere/trial_engine', '/tmp/trials.json'
    (models / 'volunteer_1_linear_fit.csv').write_text('t,x\n')
    assert reuse.engine_key(other, str(root), build='b1') == key
    # The models by content, not by folder.
    copy = tmp_path / 'copy'
    copy.mkdir()
    (copy / 'volunteer_1_linear.yaml').write_text('k: 1\n')
    assert reuse.engine_key(_command(copy), str(root), build='b1') == key
    # Everything else changes it.
    changed = [reuse.engine_key(_command(models), str(root), build='b2'),
               reuse.engine_key(_command(models, '--simulator-param', 'x=1'), str(root),
                                build='b1')]
    (copy / 'volunteer_1_linear.yaml').write_text('k: 2\n')
    changed.append(reuse.engine_key(_command(copy), str(root), build='b1'))
    for name in ('urdf/workcell.urdf', 'config/patient_default.yaml', 'recognizer_plugins.xml'):
        before = (root / name).read_text()
        (root / name).write_text(before + ' ')
        changed.append(reuse.engine_key(_command(models), str(root), build='b1'))
        (root / name).write_text(before)
    assert key not in changed and len(set(changed)) == len(changed)
    assert reuse.engine_key(_command(models), str(root), build='b1') == key
    # A file a NAME=VALUE names (a learned recognizer's model) by content too.
    model = tmp_path / 'model.json'
    model.write_text('{}')
    with_model = _command(models, '--recognizer-param', 'model=%s' % model)
    first = reuse.engine_key(with_model, str(root), build='b1')
    model.write_text('{"w": 1}')
    assert reuse.engine_key(with_model, str(root), build='b1') not in (first, key)


def test_code_outside_the_build_is_not_keyed(tmp_path, monkeypatch):
    root, models = _package(tmp_path)
    assert reuse.engine_key(_command(models), str(root), build='b1') is not None
    ours = _command(models, '--recognizer', 'python:pd_campaign.recognizers.ThresholdRecognizer')
    assert reuse.engine_key(ours, str(root), build='b1') is not None
    for extra in (['--recognizer', 'python:lab.recognizers.Mine'],
                  ['--compensator', 'python:lab.compensators.Mine']):
        command = _command(models, *extra)
        assert reuse.engine_key(command, str(root), build='b1') is None
        assert 'outside the build' in reuse.unkeyable(command, 'b1')
    assert 'not identified' in reuse.unkeyable(_command(models), None)
    monkeypatch.setenv('PEDICLE_DRILLING_PLUGIN_XML', str(tmp_path / 'plugins.xml'))
    assert reuse.engine_key(_command(models), str(root), build='b1') is None


def test_folders_with_glob_characters_are_read_as_named(tmp_path):
    root, models = _package(tmp_path)
    odd = tmp_path / 'run [1]*'
    odd.mkdir()
    (odd / 'volunteer_1_linear.yaml').write_text('k: 2\n')
    assert reuse.engine_key(_command(odd), str(root), build='b1') != reuse.engine_key(
        _command(models), str(root), build='b1')
    reuse.mark(str(odd), 'k')
    assert reuse.sources(str(odd), 'k') == [str(odd)]


def _campaign(out, trials, *extra):
    return subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--scenario', SCENARIO, '--rpm', '12000',
         '--trials', str(trials), '--jobs', '1', '--seed', '31', '--no-figures',
         '--out', str(out)] + list(extra), capture_output=True, text=True, timeout=600)


def _same_outputs(a, b):
    for name in ('trials.csv', 'summary.json', 'report.md'):
        assert filecmp.cmp(a / name, b / name, shallow=False), name
    names = sorted(os.listdir(a / 'traces'))
    assert names == sorted(os.listdir(b / 'traces'))
    match, mismatch, errors = filecmp.cmpfiles(a / 'traces', b / 'traces', names, shallow=False)
    assert not mismatch and not errors and len(match) == len(names)


def test_a_campaign_taking_trials_writes_what_running_them_writes(tmp_path):
    results = tmp_path / 'results'
    first = _campaign(results / 'first', 1)
    assert first.returncode == 0, first.stderr[-3000:]
    assert (results / 'first' / reuse.SOURCE_FILE).exists()
    second = _campaign(results / 'second', 2, '--reuse-trials', str(results))
    assert second.returncode == 0, second.stderr[-3000:]
    assert '3 taken from finished campaigns' in second.stderr
    fresh = _campaign(tmp_path / 'fresh', 2)
    assert fresh.returncode == 0, fresh.stderr[-3000:]
    _same_outputs(results / 'second', tmp_path / 'fresh')
    # Another bench's trials are not taken: the same trial entries, another engine key.
    scenario = tmp_path / 'bench.yaml'
    scenario.write_text(open(SCENARIO).read() + '\nsimulator_params: {force_noise_sd_n: 0.05}\n')
    other = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--scenario', str(scenario), '--rpm',
         '12000', '--trials', '1', '--jobs', '1', '--seed', '31', '--no-figures',
         '--reuse-trials', str(results), '--out', str(results / 'other')],
        capture_output=True, text=True, timeout=600)
    assert other.returncode == 0, other.stderr[-3000:]
    assert '0 taken from finished campaigns' in other.stderr


def test_only_finished_trials_without_error_are_taken(tmp_path):
    results = tmp_path / 'results'
    assert _campaign(results / 'first', 1).returncode == 0
    source = results / 'first'
    # A campaign running in the folder removes the mark first: nothing is taken from it.
    key = json.loads((source / reuse.SOURCE_FILE).read_text())['engine_key']
    design = json.loads((source / 'design.json').read_text())['trials']
    assert len(reuse.find(str(results), key, design)) == 3
    reuse.unmark(str(source))
    assert reuse.find(str(results), key, design) == {}
    reuse.mark(str(source), key)
    # A row with an error, or without its trace, is run again.
    with open(source / 'trials.csv') as handle:
        rows = list(csv.DictReader(handle))
    rows[0]['error'] = 'trial_engine: something failed'
    with open(source / 'trials.csv', 'w', newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    os.remove(source / 'traces' / (rows[1]['trial_id'] + '.json'))
    assert sorted(reuse.find(str(results), key, design)) == [rows[2]['trial_id']]
    # Its own folder is never a source; a changed trial entry is not the same trial.
    assert reuse.find(str(results), key, design, exclude=str(source)) == {}
    changed = [dict(t, seed=t['seed'] + 1) for t in design]
    assert reuse.find(str(results), key, changed) == {}


def test_a_source_rewritten_while_read_gives_nothing(tmp_path, monkeypatch):
    """A campaign that starts in a source's folder while it is read (it removes the mark first,
    then rewrites trials.csv): nothing is taken from it, and its half-written files are not
    reported; a source that stays marked but cannot be read gives nothing and is reported."""
    results = tmp_path / 'results'
    assert _campaign(results / 'first', 1).returncode == 0
    source = results / 'first'
    key = json.loads((source / reuse.SOURCE_FILE).read_text())['engine_key']
    design = json.loads((source / 'design.json').read_text())['trials']
    read = reuse.trials_csv.read_trials_csv

    def restarted(path):
        reuse.unmark(str(source))
        return read(path)

    monkeypatch.setattr(reuse.trials_csv, 'read_trials_csv', restarted)
    assert reuse.find(str(results), key, design) == {}

    def restarted_and_empty(path):
        reuse.unmark(str(source))
        raise ValueError('%s: missing columns trial_id' % path)

    reuse.mark(str(source), key)
    monkeypatch.setattr(reuse.trials_csv, 'read_trials_csv', restarted_and_empty)
    assert reuse.find(str(results), key, design) == {}

    def broken(path):
        raise ValueError('%s: missing columns trial_id' % path)

    reuse.mark(str(source), key)
    monkeypatch.setattr(reuse.trials_csv, 'read_trials_csv', broken)
    unreadable = []
    assert reuse.find(str(results), key, design, unreadable=unreadable) == {}
    assert len(unreadable) == 1 and unreadable[0].startswith(str(source) + ': ')
    monkeypatch.setattr(reuse.trials_csv, 'read_trials_csv', read)
    assert len(reuse.find(str(results), key, design)) == 3


@pytest.mark.parametrize('extra, message', [
    (['--engine', 'ros'], 'use it with --engine core'),
    (['--samples'], 'not with --samples or --profile'),
    (['--profile'], 'not with --samples or --profile'),
])
def test_refused_combinations(tmp_path, extra, message):
    result = _campaign(tmp_path / 'out', 1, '--reuse-trials', str(tmp_path), *extra)
    assert result.returncode == 2
    assert message in result.stderr
    assert not (tmp_path / 'out' / 'trials.csv').exists()


def test_a_missing_root_is_refused(tmp_path):
    result = _campaign(tmp_path / 'out', 1, '--reuse-trials', str(tmp_path / 'absent'))
    assert result.returncode == 2
    assert '--reuse-trials %s is not a folder' % (tmp_path / 'absent') in result.stderr
    assert not (tmp_path / 'out' / 'trials.csv').exists()


def test_a_merged_folder_is_no_source(tmp_path):
    results = tmp_path / 'results'
    assert _campaign(results / 'first', 1).returncode == 0
    merged = results / 'merged'
    merged.mkdir()
    reuse.mark(str(merged), 'an earlier campaign of this folder')
    result = subprocess.run(['rosrun', 'pedicle_drilling', 'campaign_merge',
                             str(results / 'first'), '--out', str(merged)],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    assert (merged / 'trials.csv').exists()
    assert not (merged / reuse.SOURCE_FILE).exists()

"""doc/campaign_results.md's sweep tables (scripts/dev/sensitivity_tables.py) on a small sweep
written here: the cells, the bold ends, the conclusions, and the archived form of a sweep read as
a make run output's."""
import csv
import importlib.util
import json
import os

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
# Loaded from its file: the test leaves the import path alone.
_SPEC = importlib.util.spec_from_file_location(
    'sensitivity_tables', os.path.join(ROOT, 'scripts', 'dev', 'sensitivity_tables.py'))
sensitivity_tables = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(sensitivity_tables)

COLUMNS = ['case', 'rpm', 'constant', 'unit', 'low', 'nominal', 'high', 'successes_low',
           'successes_nominal', 'successes_high', 'trials_nominal', 'mcnemar_p_low',
           'mcnemar_p_high']
# (case, constant, successes low / nominal / high, McNemar p low / high)
ROWS = [('stationary', 'simulator_params.a', (18, 19, 12), (1.0, 0.016)),
        ('compensated', 'simulator_params.a', (19, 19, 19), (1.0, 1.0)),
        ('stationary', 'simulator_params.b', (20, 19, 19), (1.0, 1.0))]
ENDS = [{'key': 'simulator_params.a', 'end': 'high', 'value': 3.0, 'holds': False,
         'detail': 'fails', 'id': 'x', 'extra': 1},
        {'key': 'simulator_params.b', 'end': 'low', 'value': 1.0, 'holds': True,
         'detail': 'holds', 'id': 'y', 'extra': 2}]
CONCLUSIONS = [{'id': 'c', 'title': 'Compensated equals stationary', 'rule': 'r',
                'nominal': {'holds': True, 'detail': 'nominal detail'}, 'ends': ENDS,
                'fails_at': ENDS[:1], 'holds_over_range': False},
               {'id': 's', 'title': 'Speed', 'rule': 'r',
                'nominal': {'holds': None, 'detail': 'needs several speeds'}, 'ends': [],
                'fails_at': [], 'holds_over_range': None}]


@pytest.fixture
def sweep(tmp_path):
    folder = tmp_path / 'results' / 'sensitivity_paper'
    folder.mkdir(parents=True)
    with open(folder / 'sensitivity.csv', 'w') as handle:
        writer = csv.DictWriter(handle, fieldnames=COLUMNS)
        writer.writeheader()
        for case, constant, successes, p in ROWS:
            writer.writerow(dict(zip(COLUMNS, [case, '12000', constant, 'mm', '1', '2', '3']
                                     + list(successes) + [20] + list(p))))
    (folder / 'sensitivity.json').write_text(json.dumps({'groups': [],
                                                          'conclusions': CONCLUSIONS}))
    return tmp_path


def test_a_cell_is_low_nominal_high_with_a_significant_end_in_bold(sweep):
    table = sensitivity_tables.screen_table(str(sweep / 'results'), 'sensitivity_paper')
    row_a, row_b = table.splitlines()[2:]
    assert row_a.startswith('| `a` | 1 / 2 / 3 mm |')
    assert '| 18 / 19 / **12** of 20 |' in row_a          # p 0.016 at the high end
    assert row_a.endswith('| 19 / 19 / 19 of 20 |')       # compensated, nothing significant
    assert '| - |' in row_b                               # no uncompensated row


def test_the_conclusions_count_the_ends_and_name_the_failures(sweep):
    table = sensitivity_tables.conclusions_table(str(sweep / 'results'), 'sensitivity_paper')
    lines = table.splitlines()
    assert len(lines) == 3                                # the unevaluated conclusion left out
    assert lines[2] == ('| Compensated equals stationary | holds (nominal detail) | 1 of 2 | '
                        '`a` = 3.0 |')


def test_an_archived_sweep_archives_to_itself(sweep):
    results, archive, again = (str(sweep / name) for name in ('results', 'archive', 'again'))
    for source, target in ((results, archive), (archive, again)):
        sensitivity_tables.archive_sweep(os.path.join(source, 'sensitivity_paper'),
                                         os.path.join(target, 'sensitivity_paper'))
    for name in ('sensitivity.csv', 'conclusions.json'):
        with open(os.path.join(archive, 'sensitivity_paper', name)) as a, \
                open(os.path.join(again, 'sensitivity_paper', name)) as b:
            assert a.read() == b.read()
    with open(os.path.join(archive, 'sensitivity_paper', 'conclusions.json')) as handle:
        kept = json.load(handle)
    assert 'extra' not in kept[0]['ends'][0]
    assert sensitivity_tables.conclusions_table(archive, 'sensitivity_paper') == \
        sensitivity_tables.conclusions_table(results, 'sensitivity_paper')

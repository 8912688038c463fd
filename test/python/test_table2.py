"""scripts/table2.py: Table II for the five virtual volunteers. AP and SI slopes within 5 % of
the generator's truth (checked here against the truth files, not the script's own column), the
hysteresis model's R^2 beside the linear one's, and the files' schema."""
import csv
import os
import subprocess

import pytest
import yaml

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
FIELDS = ['volunteer', 'model', 'axis', 'wavelet', 'q1', 'q2', 'q0', 'r2', 'rmse', 'q1_true',
          'q2_true', 'q1_rel_err']


@pytest.fixture(scope='module')
def table2(tmp_path_factory, bin_dir):
    out = tmp_path_factory.mktemp('table2')
    env = dict(os.environ, PEDICLE_DRILLING_BIN_DIR=bin_dir)
    run = subprocess.run(['/usr/bin/python3', os.path.join(ROOT, 'scripts', 'table2.py'),
                          '--out', str(out)], capture_output=True, text=True, timeout=300,
                         env=env)
    assert run.returncode == 0, run.stderr
    with open(out / 'table2.csv') as f:
        rows = list(csv.DictReader(f))
    return out, run.stdout, rows


def test_csv_schema_and_rows(table2):
    _, _, rows = table2
    assert list(rows[0].keys()) == FIELDS
    assert len(rows) == 5 * 2 * 3
    keys = {(r['volunteer'], r['model'], r['axis']) for r in rows}
    assert keys == {(str(v), m, a) for v in range(1, 6) for m in ('linear', 'hysteresis')
                    for a in ('ap', 'si', 'lr')}
    for r in rows:
        assert 0.0 < float(r['r2']) <= 1.0
        if r['model'] == 'linear':
            assert float(r['q2']) == 0.0


def test_ap_si_slopes_within_5_percent_of_truth(table2):
    out, _, rows = table2
    for r in rows:
        if r['axis'] == 'lr':
            continue
        with open(out / 'data' / ('volunteer_%s_truth.yaml' % r['volunteer'])) as f:
            truth = yaml.safe_load(f)['axes'][r['axis']]['q1']
        with open(out / 'models' / ('volunteer_%s_%s.yaml' % (r['volunteer'], r['model']))) as f:
            identified = yaml.safe_load(f)['axes'][r['axis']]['q1']
        assert float(r['q1']) == pytest.approx(identified, rel=1e-9)
        assert abs(identified / truth - 1.0) < 0.05, r


def test_hysteresis_r2_beside_linear_and_not_worse(table2):
    _, _, rows = table2
    r2 = {(r['volunteer'], r['model'], r['axis']): float(r['r2']) for r in rows}
    for v in range(1, 6):
        for a in ('ap', 'si', 'lr'):
            # The hysteresis model nests the linear one (q2 = 0), fitted on the same data.
            assert r2[(str(v), 'hysteresis', a)] >= r2[(str(v), 'linear', a)] - 1e-12


def test_markdown_table_and_figure(table2):
    out, stdout, rows = table2
    md = (out / 'table2.md').read_text()
    assert md in stdout
    lines = md.splitlines()
    header = next(i for i, l in enumerate(lines) if l.startswith('| volunteer | R²'))
    assert lines[header].count('|') == 8
    body = lines[header + 2:header + 8]
    assert [l.split('|')[1].strip() for l in body] == ['1', '2', '3', '4', '5', '**mean**']
    # The mean row is the mean of the CSV's R^2 (AP linear column).
    mean_ap = sum(float(r['r2']) for r in rows
                  if r['axis'] == 'ap' and r['model'] == 'linear') / 5.0
    assert float(body[5].split('|')[2].strip().strip('*')) == pytest.approx(mean_ap, abs=6e-5)
    png = out / 'table2_fig14.png'
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert png.stat().st_size > 20000


def test_no_figure_writes_the_same_table_and_models_without_the_plot(table2, tmp_path, bin_dir):
    """--no-figure (the campaign's identification): the same table and models, no plot."""
    out, _, _ = table2
    env = dict(os.environ, PEDICLE_DRILLING_BIN_DIR=bin_dir)
    run = subprocess.run(['/usr/bin/python3', os.path.join(ROOT, 'scripts', 'table2.py'),
                          '--out', str(tmp_path), '--no-figure', '--jobs', '2'],
                         capture_output=True, text=True, timeout=300, env=env)
    assert run.returncode == 0, run.stderr
    assert not (tmp_path / 'table2_fig14.png').exists()
    for name in ('table2.md', 'table2.csv', 'models/volunteer_3_linear.yaml',
                 'models/volunteer_5_hysteresis.yaml'):
        assert (tmp_path / name).read_bytes() == (out / name).read_bytes(), name

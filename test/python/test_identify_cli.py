"""identify CLI on bad input: exit status 2, a message naming the problem, and no model file
(nor a temporary file) left in the output directory."""
import os
import subprocess

import pytest


@pytest.fixture(scope='module')
def good_csv(tmp_path_factory, bin_dir):
    d = tmp_path_factory.mktemp('volunteers')
    out = subprocess.run([os.path.join(bin_dir, 'generate_volunteers'), '--out', str(d),
                          '--ids', '1'], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return (d / 'volunteer_1.csv').read_text().splitlines()


def write(path, lines):
    path.write_text('\n'.join(lines) + '\n')
    return str(path)


def drop_column(lines, name):
    header = lines[0].split(',')
    k = header.index(name)
    return [','.join(f for i, f in enumerate(l.split(',')) if i != k) for l in lines]


def set_cell(lines, row, name, value):
    k = lines[0].split(',').index(name)
    out = list(lines)
    fields = out[row].split(',')
    fields[k] = value
    out[row] = ','.join(fields)
    return out


def swap_rows(lines, a, b):
    out = list(lines)
    out[a], out[b] = out[b], out[a]
    return out


CASES = {
    'missing_column': (lambda l: drop_column(l, 'si'), [], ["'si'"]),
    'nan': (lambda l: set_cell(l, 50, 'ap', 'nan'), [], ['NaN', "'ap'"]),
    'non_increasing_time': (lambda l: swap_rows(l, 30, 31), [], ['increasing']),
    'too_few_breaths': (lambda l: l[:21], [], ['two breaths']),
    'unknown_wavelet': (lambda l: l, ['--wavelets', 'coif4,db99'], ["db99"]),
}


@pytest.mark.parametrize('case', sorted(CASES))
def test_bad_input_exit_2_names_problem_writes_nothing(tmp_path, bin_dir, good_csv, case):
    mutate, extra, names = CASES[case]
    csv_path = write(tmp_path / 'rec.csv', mutate(good_csv))
    out_dir = tmp_path / 'out'
    out_dir.mkdir()
    model = out_dir / 'model.yaml'
    run = subprocess.run([os.path.join(bin_dir, 'identify'), '--input', csv_path, '--output',
                          str(model)] + extra, capture_output=True, text=True, timeout=60)
    assert run.returncode == 2, (run.stdout, run.stderr)
    for n in names:
        assert n in run.stderr, run.stderr
    assert os.listdir(out_dir) == []


def test_good_input_writes_model_and_no_temp_file(tmp_path, bin_dir, good_csv):
    csv_path = write(tmp_path / 'rec.csv', good_csv)
    out_dir = tmp_path / 'out'
    out_dir.mkdir()
    run = subprocess.run([os.path.join(bin_dir, 'identify'), '--input', csv_path, '--output',
                          str(out_dir / 'model.yaml')], capture_output=True, text=True,
                         timeout=60)
    assert run.returncode == 0, run.stderr
    assert os.listdir(out_dir) == ['model.yaml']
    for axis in ('ap:', 'si:', 'lr:'):
        assert axis in run.stdout

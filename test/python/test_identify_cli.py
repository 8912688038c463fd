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


def identify(bin_dir, csv_path, model, *extra):
    """Runs identify on csv_path, writing model; returns the finished process."""
    return subprocess.run([os.path.join(bin_dir, 'identify'), '--input', str(csv_path),
                           '--output', str(model)] + [str(e) for e in extra],
                          capture_output=True, text=True, timeout=60)


def prepared(tmp_path, good_csv):
    """The recording written to tmp_path and an empty output folder."""
    csv_path = write(tmp_path / 'rec.csv', good_csv)
    out_dir = tmp_path / 'out'
    out_dir.mkdir()
    return csv_path, out_dir


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


def scale_columns(lines, names, factor=None, constant=None):
    """Finite but extreme input: the named columns multiplied by `factor` or set to `constant`."""
    header = lines[0].split(',')
    keys = [header.index(n) for n in names]
    out = [lines[0]]
    for line in lines[1:]:
        fields = line.split(',')
        for k in keys:
            fields[k] = repr(constant if constant is not None else float(fields[k]) * factor)
        out.append(','.join(fields))
    return out


CASES = {
    'missing_column': (lambda l: drop_column(l, 'si'), [], ["'si'"]),
    'nan': (lambda l: set_cell(l, 50, 'ap', 'nan'), [], ['NaN', "'ap'"]),
    'non_increasing_time': (lambda l: swap_rows(l, 30, 31), [], ['increasing']),
    'too_few_breaths': (lambda l: l[:21], [], ['two breaths']),
    'unknown_wavelet': (lambda l: l, ['--wavelets', 'coif4,db99'], ["db99"]),
    # Finite but extreme input once gave `R2 -nan RMSE inf`, a model file the planner refuses,
    # and exit 0: the model is checked before anything is written.
    'extreme_scale': (lambda l: scale_columns(l, ['tv', 'ap'], factor=1e300), [],
                      ['not a finite number']),
    'extreme_constant': (lambda l: scale_columns(l, ['ap'], constant=1e300), [],
                         ['not a finite number']),
}


@pytest.mark.parametrize('case', sorted(CASES))
def test_bad_input_exit_2_names_problem_writes_nothing(tmp_path, bin_dir, good_csv, case):
    mutate, extra, names = CASES[case]
    csv_path, out_dir = prepared(tmp_path, mutate(good_csv))
    run = identify(bin_dir, csv_path, out_dir / 'model.yaml', *extra)
    assert run.returncode == 2, (run.stdout, run.stderr)
    for n in names:
        assert n in run.stderr, run.stderr
    assert os.listdir(out_dir) == []


def test_good_input_writes_model_and_no_temp_file(tmp_path, bin_dir, good_csv):
    csv_path, out_dir = prepared(tmp_path, good_csv)
    run = identify(bin_dir, csv_path, out_dir / 'model.yaml')
    assert run.returncode == 0, run.stderr
    assert os.listdir(out_dir) == ['model.yaml']
    for axis in ('ap:', 'si:', 'lr:'):
        assert axis in run.stdout


AXIS_LINE = (r'^(ap|si|lr): wavelet (\S+)\s+q1 (\S+) mm/ml  q2 (\S+) mm\*s/ml  q0 (\S+) mm  '
             r'R2 (\S+) \(raw (\S+)\)  RMSE (\S+) mm  \d+ it  (\S+) ms(.*)$')


def axis_lines(stdout):
    import re
    found = {}
    for line in stdout.splitlines():
        match = re.match(AXIS_LINE, line.strip())
        if match:
            found[match.group(1)] = match.groups()
    return found


@pytest.mark.parametrize('method', ['ceres', 'pso'])
def test_report_prints_wavelet_coefficients_r2_time_and_stiffness(tmp_path, bin_dir, good_csv,
                                                                  method):
    """Per axis: chosen wavelet, q1/q2/q0, R^2, time taken and (AP, SI) the equivalent disc
    stiffness implied with Table I; the model file agrees with what was printed."""
    csv_path = write(tmp_path / 'rec.csv', good_csv)
    model = tmp_path / 'model.yaml'
    run = subprocess.run([os.path.join(bin_dir, 'identify'), '--input', csv_path, '--output',
                          str(model), '--method', method, '--wavelets', 'coif4,bior2.8,coif5'],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    lines = axis_lines(run.stdout)
    assert sorted(lines) == ['ap', 'lr', 'si'], run.stdout
    for axis, groups in lines.items():
        wavelet, q1, r2, ms, tail = groups[1], float(groups[2]), float(groups[5]), \
            float(groups[8]), groups[9]
        assert wavelet in ('coif4', 'bior2.8', 'coif5')
        assert 0.5 < r2 <= 1.0 and ms >= 0.0
        if axis == 'lr':
            assert 'stiffness' not in tail
        else:
            assert q1 > 0.0
            unit = 'mm^6' if axis == 'ap' else 'mm^2'
            assert 'stiffness' in tail and unit in tail, tail
            stiffness = float(tail.split()[1])
            assert stiffness > 0.0
    text = model.read_text()
    assert 'equivalent_stiffness' in text
    ap_q1 = float(lines['ap'][2])
    assert abs(float(text.split('q1: ')[1].split()[0]) - ap_q1) <= 1e-5 * abs(ap_q1)


def test_unwritable_fit_csv_leaves_no_output_at_all(tmp_path, bin_dir, good_csv):
    """--fit-csv into a folder that does not exist once wrote the model and then exited 1: every
    output's destination is checked before any is written, so nothing is kept."""
    csv_path, out_dir = prepared(tmp_path, good_csv)
    run = identify(bin_dir, csv_path, out_dir / 'model.yaml', '--fit-csv',
                   tmp_path / 'missing' / 'fit.csv')
    assert run.returncode == 1, (run.stdout, run.stderr)
    assert 'fit.csv' in run.stderr and 'missing' in run.stderr, run.stderr
    assert os.listdir(out_dir) == []


def test_fit_csv_and_model_are_written_together(tmp_path, bin_dir, good_csv):
    csv_path, out_dir = prepared(tmp_path, good_csv)
    run = identify(bin_dir, csv_path, out_dir / 'model.yaml', '--fit-csv', out_dir / 'fit.csv')
    assert run.returncode == 0, run.stderr
    assert sorted(os.listdir(out_dir)) == ['fit.csv', 'model.yaml']
    lines = (out_dir / 'fit.csv').read_text().splitlines()
    assert lines[0].startswith('t,tv,ap_raw,ap_fit,ap_model,ap_tv')
    assert len(lines) == len(good_csv)


def test_generate_volunteers_and_identify_count_the_same_breaths(tmp_path, bin_dir):
    """One definition of a breath: generate_volunteers once reported 10 breaths where identify
    reported 9 for the same recording."""
    import re
    for vid in ('1', '2', '3', '4', '5'):
        gen = subprocess.run([os.path.join(bin_dir, 'generate_volunteers'), '--out',
                              str(tmp_path), '--ids', vid], capture_output=True, text=True,
                             timeout=60)
        assert gen.returncode == 0, gen.stderr
        generated = int(re.search(r'volunteer %s: (\d+) breaths' % vid, gen.stdout).group(1))
        ident = identify(bin_dir, tmp_path / ('volunteer_%s.csv' % vid),
                         tmp_path / ('model_%s.yaml' % vid))
        assert ident.returncode == 0, ident.stderr
        identified = int(re.search(r'(\d+) breaths', ident.stdout).group(1))
        assert generated == identified, (vid, gen.stdout, ident.stdout)

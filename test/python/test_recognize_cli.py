"""The recognize CLI over raw force samples: key points and stop, JSON schema, bad input."""
import json
import math
import os
import random
import subprocess

import pytest

RATE_HZ = 1000.0


def profile(layers, seed=1):
    """Synthetic thrust at 1 kHz: air, then (duration s, level N) plateaus joined by 0.3 s
    ramps, with seeded sensor noise; returns rows and the start/end time of each layer."""
    rng = random.Random(seed)
    rows, t, level, spans = [], 0.0, 0.0, []
    pieces = [(2.0, 0.0)] + layers + [(2.0, 0.0)]
    for duration, target in pieces:
        start = t
        ramp = 0.3
        n = int(duration * RATE_HZ)
        for k in range(n):
            frac = min(1.0, k / (ramp * RATE_HZ))
            value = level + (target - level) * frac
            rows.append((t, value + rng.gauss(0.0, 0.03)))
            t += 1.0 / RATE_HZ
        spans.append((start, t, target))
        level = target
    return rows, spans


def write_csv(path, rows, header='t,force'):
    with open(path, 'w') as handle:
        handle.write(header + '\n')
        for t, f in rows:
            handle.write('%.6f,%.6f\n' % (t, f))


def run(bin_dir, *args):
    return subprocess.run([os.path.join(bin_dir, 'recognize')] + list(args),
                          capture_output=True, text=True, timeout=60)


def test_two_cortical_layers_stop_inside_the_inner_one(bin_dir, tmp_path):
    rows, spans = profile([(4.0, 3.0), (6.0, 0.7), (4.0, 3.0)])
    path = tmp_path / 'force.csv'
    write_csv(path, rows)
    out = run(bin_dir, '--input', str(path), '--json')
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert set(result) == {'key_points', 'stop'}
    times = [kp['t'] for kp in result['key_points']]
    assert times == sorted(times) and len(times) >= 4
    for kp in result['key_points']:
        assert set(kp) == {'index', 't'}
        assert rows[kp['index']][0] == pytest.approx(kp['t'], abs=1e-6)
    inner_start, inner_end = spans[3][0], spans[3][1]
    assert result['stop'] is not None
    assert inner_start < result['stop']['t'] < inner_end
    assert rows[result['stop']['index']][0] == pytest.approx(result['stop']['t'], abs=1e-6)


def test_one_layer_never_stops(bin_dir, tmp_path):
    rows, _ = profile([(4.0, 3.0), (8.0, 0.7)])
    path = tmp_path / 'force.csv'
    write_csv(path, rows)
    out = run(bin_dir, '--input', str(path), '--json')
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)['stop'] is None


@pytest.mark.parametrize('case', ['missing', 'header', 'nan', 'time', 'param',
                                  'inputs without json', 'param twice'])
def test_bad_input_exits_2(bin_dir, tmp_path, case):
    rows, _ = profile([(2.0, 3.0)])
    path = tmp_path / 'force.csv'
    args = ['--input', str(path)]
    if case == 'missing':
        args = ['--input', str(tmp_path / 'nope.csv')]
    elif case == 'header':
        write_csv(path, rows, header='time,thrust')
    elif case == 'nan':
        rows[100] = (rows[100][0], math.nan)
        write_csv(path, rows)
    elif case == 'time':
        rows[100] = (rows[99][0], rows[100][1])
        write_csv(path, rows)
    elif case == 'param':
        write_csv(path, rows)
        args += ['--param', 'c3=-1']
    elif case == 'inputs without json':  # several traces: one JSON line each, or nothing
        write_csv(path, rows)
        args += ['--input', str(path)]
    elif case == 'param twice':
        write_csv(path, rows)
        args += ['--param', 'c3=2', '--param', 'c3=3']
    out = run(bin_dir, *args)
    assert out.returncode == 2, (case, out.stdout, out.stderr)
    assert out.stderr.strip()
    if case.endswith('twice'):
        assert 'given more than once' in out.stderr, out.stderr
    if case == 'inputs without json':
        assert 'need --json' in out.stderr, out.stderr


def test_several_traces_give_one_line_each_as_alone(bin_dir, tmp_path):
    """--json with several --input: one line per trace, in order, each the line of that trace
    run alone (the recognizer reset between traces) plus its path."""
    paths = []
    for k, profile_steps in enumerate([[(4.0, 3.0), (6.0, 0.7), (4.0, 3.0)], [(2.0, 3.0)],
                                       [(4.0, 3.0), (6.0, 0.7), (4.0, 3.0)]]):
        rows, _ = profile(profile_steps, seed=10 + k)
        paths.append(tmp_path / ('force%d.csv' % k))
        write_csv(paths[-1], rows)
    args = ['--json']
    for path in paths:
        args += ['--input', str(path)]
    out = run(bin_dir, *args)
    assert out.returncode == 0, out.stderr
    lines = [json.loads(line) for line in out.stdout.splitlines()]
    assert [line.pop('input') for line in lines] == [str(p) for p in paths]
    for path, line in zip(paths, lines):
        alone = run(bin_dir, '--json', '--input', str(path))
        assert json.loads(alone.stdout) == line


def test_text_output_agrees_with_json(bin_dir, tmp_path):
    """Without --json: one line per key point ('key_point ID index I t T') and the stop
    ('stop index I t T' or 'stop none'), the same as the JSON of the same input."""
    rows, _ = profile([(4.0, 3.0), (6.0, 0.7), (4.0, 3.0)], seed=4)
    path = tmp_path / 'force.csv'
    write_csv(path, rows)
    text = run(bin_dir, '--input', str(path))
    js = run(bin_dir, '--input', str(path), '--json')
    assert text.returncode == 0 and js.returncode == 0, text.stderr + js.stderr
    result = json.loads(js.stdout)
    lines = text.stdout.splitlines()
    assert lines[0] == 'samples %d' % len(rows)
    key_points = [line.split() for line in lines if line.startswith('key_point ')]
    assert [int(k[3]) for k in key_points] == [kp['index'] for kp in result['key_points']]
    assert [float(k[5]) for k in key_points] == pytest.approx(
        [kp['t'] for kp in result['key_points']], abs=1e-6)
    stop = [line.split() for line in lines if line.startswith('stop ')]
    assert len(stop) == 1
    assert int(stop[0][2]) == result['stop']['index']
    assert float(stop[0][4]) == pytest.approx(result['stop']['t'], abs=1e-6)
    # The stop names the key point it was commanded at: 4 (confirmed) or 5 (fail-safe).
    assert stop[0][5] == 'key_point' and int(stop[0][6]) == result['stop']['key_point']
    assert result['stop']['key_point'] in (4, 5)


def test_param_sets_give_each_sets_lines_as_run_alone(bin_dir, tmp_path):
    """--param-sets: every set's recognizer over every trace, the sets in file order, each line
    the one of that set run alone with its items as --param (added to the --param given)."""
    paths = []
    for k, profile_steps in enumerate([[(4.0, 3.0), (6.0, 0.7), (4.0, 3.0)], [(2.0, 3.0)]]):
        rows, _ = profile(profile_steps, seed=20 + k)
        paths.append(tmp_path / ('force%d.csv' % k))
        write_csv(paths[-1], rows)
    sets = ['f_th=0.2', '', 'f_th=0.6 window=5']
    (tmp_path / 'sets.txt').write_text(''.join(line + '\n' for line in sets))
    inputs = [arg for path in paths for arg in ('--input', str(path))]
    out = run(bin_dir, '--json', '--param', 'k_ratio=0.5', '--param-sets',
              str(tmp_path / 'sets.txt'), *inputs)
    assert out.returncode == 0, out.stderr
    lines = [json.loads(line) for line in out.stdout.splitlines()]
    assert [line.pop('param_set') for line in lines] == [0, 0, 1, 1, 2, 2]
    alone = []
    for line in sets:
        params = [arg for item in line.split() for arg in ('--param', item)]
        result = run(bin_dir, '--json', '--param', 'k_ratio=0.5', *params, *inputs)
        assert result.returncode == 0, result.stderr
        alone += [json.loads(text) for text in result.stdout.splitlines()]
    assert lines == alone
    assert lines[0]['stop'] != lines[4]['stop'], 'the sets must differ somewhere'


@pytest.mark.parametrize('text, extra, message', [
    ('f_th=0.2\n', [], '--param-sets needs --json'),
    ('f_th=0.2\nwindow\n', ['--json'], "line 2"),
    ('f_th=0.2 f_th=0.3\n', ['--json'], "--param-sets line 1: option '--param f_th' given more"),
    ('k_ratio=0.7\n', ['--json', '--param', 'k_ratio=0.5'], "given more than once"),
    ('no_such=1\n', ['--json'], '--param-sets line 1: --recognizer'),
    ('', ['--json'], 'has no line'),
])
def test_bad_param_sets_exit_2_printing_nothing(bin_dir, tmp_path, text, extra, message):
    rows, _ = profile([(2.0, 3.0)], seed=3)
    write_csv(tmp_path / 'force.csv', rows)
    (tmp_path / 'sets.txt').write_text(text)
    out = run(bin_dir, '--param-sets', str(tmp_path / 'sets.txt'), '--input',
              str(tmp_path / 'force.csv'), *extra)
    assert out.returncode == 2
    assert message in out.stderr
    assert out.stdout == ''

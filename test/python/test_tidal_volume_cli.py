"""The tidal_volume CLI: CSV output for the paper's settings and exit status 2 on bad input."""
import csv
import io
import os
import subprocess

import pytest


def run(bin_dir, *args):
    return subprocess.run([os.path.join(bin_dir, 'tidal_volume')] + list(args),
                          capture_output=True, text=True, timeout=60)


def test_paper_settings_csv(bin_dir):
    out = run(bin_dir, '--tv-max', '500', '--rate', '12', '--ie', '1:2', '--waveform', 'square',
              '--fs', '64', '--duration', '10')
    assert out.returncode == 0, out.stderr
    rows = list(csv.DictReader(io.StringIO(out.stdout)))
    assert list(rows[0].keys()) == ['t', 'flow', 'volume']
    assert len(rows) == 640
    t = [float(r['t']) for r in rows]
    assert t[1] - t[0] == pytest.approx(1.0 / 64.0)
    flows = [float(r['flow']) for r in rows]
    volumes = [float(r['volume']) for r in rows]
    assert flows[10] == pytest.approx(300.0, abs=1e-3)
    assert max(volumes) == pytest.approx(500.0, abs=300.0 / 64.0)
    assert min(flows) == pytest.approx(-450.0, rel=0.01)
    # Two full breaths: the volume at t = 5 s equals the volume at t = 0.
    assert volumes[320] == pytest.approx(volumes[0], abs=0.5)


@pytest.mark.parametrize('args, named', [
    (['--rate', '0'], '--rate'),
    (['--rate', '-3'], '--rate'),
    (['--ie', '12'], '--ie'),
    (['--ie', 'a:b'], '--ie'),
    (['--waveform', 'triangle'], '--waveform'),
    (['--tv-max', '0'], '--tv-max'),
    (['--tv-max', '-500'], '--tv-max'),
    (['--tv-max', 'nan'], '--tv-max'),
    (['--fs', 'x'], '--fs'),
    (['--bogus', '1'], '--bogus'),
    # A repeated option once ran silently with the first value (rate 12): refused by every tool.
    (['--rate', '12', '--ie', '1:2', '--rate', '0'], "'--rate' given more than once"),
])
def test_bad_arguments_exit_2_and_name_the_argument(bin_dir, args, named):
    out = run(bin_dir, *args)
    assert out.returncode == 2
    assert named in out.stderr
    assert out.stdout == ''

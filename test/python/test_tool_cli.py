"""The command-line conventions shared by the seven C++ tools (CLI11, src/tools/tool_cli.hpp):
--help prints the usage and exits 0; an unknown option, a bad value (not a number, out of
range, NaN or infinite, not one of the choices), a missing required option and an option given
twice exit 2 with a message on stderr that names the option, and nothing on stdout."""
import os
import subprocess

import pytest

POSE = '0,0.435859,1.319709,0,1.386025,0'  # config/drilling_pose.yaml

# Per tool: its required options (with values good enough for the parser: nothing is read
# before the command line is accepted), one option with a good and a bad value.
TOOLS = {
    'denoise': (['--wavelet', 'coif4'], '--level', '5', '33'),
    'dwt_coeffs': (['--wavelet', 'db4'], '--level', '5', 'x'),
    'generate_volunteers': (['--out', 'never_written'], '--duration', '30', 'nan'),
    'identify': (['--input', 'rec.csv', '--output', 'never_written.yaml'], '--delta-tv', '5',
                 'nan'),
    'param_docs': ([], '--format', 'json', 'yaml'),
    'recognize': (['--input', 'force.csv'], '--axis', '-z', 'w'),
    'tidal_volume': ([], '--fs', '64', 'inf'),
    'trial_engine': (['--trials', 'trials.json', '--drilling-pose', POSE], '--feed-rate', '0.5',
                     'nan'),
}


def run(bin_dir, cwd, tool, *args):
    """The tool in cwd (its relative paths: nothing may be written there, and nothing is)."""
    return subprocess.run([os.path.join(bin_dir, tool)] + list(args), capture_output=True,
                          text=True, timeout=60, stdin=subprocess.DEVNULL, cwd=str(cwd))


@pytest.mark.parametrize('tool', sorted(TOOLS))
def test_help_unknown_option_bad_value_and_repeat(bin_dir, tmp_path, tool):
    required, option, good, bad = TOOLS[tool]
    out = run(bin_dir, tmp_path, tool, '--help')
    assert out.returncode == 0, out.stderr
    assert 'Usage' in out.stdout and option in out.stdout, out.stdout
    # An unknown option is named first, even before a required option that is missing.
    for args in (['--no-such-option'], required + ['--no-such-option', '1']):
        out = run(bin_dir, tmp_path, tool, *args)
        assert out.returncode == 2, (args, out.stdout, out.stderr)
        assert '--no-such-option' in out.stderr and out.stdout == '', (args, out.stderr)
    out = run(bin_dir, tmp_path, tool, *(required + [option, bad]))
    assert out.returncode == 2, (bad, out.stdout, out.stderr)
    assert option in out.stderr and out.stdout == '', out.stderr
    out = run(bin_dir, tmp_path, tool, *(required + [option, good, option, good]))
    assert out.returncode == 2, (out.stdout, out.stderr)
    assert "'%s' given more than once" % option in out.stderr and out.stdout == '', out.stderr
    if required:
        out = run(bin_dir, tmp_path, tool, *required[2:])
        assert out.returncode == 2, (out.stdout, out.stderr)
        assert required[0] in out.stderr and out.stdout == '', out.stderr
    assert os.listdir(tmp_path) == []

"""The Slurm job-array recipe of doc/experiments.md, run for real in `make test`:
test/slurm/slurm_campaign.sh starts a one-node Slurm cluster on loopback (slurm-wlm and munge
come from `make deps`; the script installs them when missing), submits that page's job script
as a 3-shard array, merges the shards with its campaign_merge line as a dependent job, and
checks the merged report against a single run of the same design (about a minute). It stops
its daemons on exit; this test checks that nothing it started is left running. The daemons
need root, as `make deps` does: a run as another user fails saying so.
PEDICLE_DRILLING_SLURM_TESTS=0 leaves it out (a machine where Slurm daemons may not run)."""
import os
import re
import signal
import subprocess
import time

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
SCRIPT = os.path.join(ROOT, 'test', 'slurm', 'slurm_campaign.sh')
SLURM = os.environ.get('PEDICLE_DRILLING_SLURM_TESTS', '1') != '0'
TIMEOUT_S = 1800  # apt-get install included


def processes_with_env(entry):
    """Ids of the processes whose environment holds `entry` (NAME=value)."""
    wanted = entry.encode()
    found = []
    for name in os.listdir('/proc'):
        if not name.isdigit():
            continue
        try:
            with open(os.path.join('/proc', name, 'environ'), 'rb') as handle:
                if wanted in handle.read().split(b'\0'):
                    found.append(int(name))
        except OSError:
            continue  # gone, or not ours to read
    return found


def test_script_is_executable():
    assert os.access(SCRIPT, os.X_OK), SCRIPT


@pytest.mark.skipif(not SLURM, reason='left out: PEDICLE_DRILLING_SLURM_TESTS=0')
def test_slurm_job_array_merges_to_the_single_run(tmp_path, bin_dir):
    assert os.geteuid() == 0, ('the Slurm daemons of the test cluster need root (as make deps '
                               'does); PEDICLE_DRILLING_SLURM_TESTS=0 leaves this test out')
    # Every process the script starts inherits this TMPDIR, which is how leftovers are found below
    # (its cluster directory goes to /tmp when TMPDIR is too deep for the daemons' sockets).
    env = dict(os.environ, TMPDIR=str(tmp_path), PEDICLE_DRILLING_BIN_DIR=bin_dir)
    start = time.time()
    script = subprocess.Popen([SCRIPT], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              env=env, text=True)
    try:
        output, _ = script.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        script.send_signal(signal.SIGTERM)  # its trap cancels the jobs and stops the daemons
        output, _ = script.communicate(timeout=180)
        output += '\n(test: timed out after %d s, SIGTERM sent)' % TIMEOUT_S
    print(output)
    print('slurm_campaign.sh: exit %s after %.0f s' % (script.returncode, time.time() - start))
    left = processes_with_env('TMPDIR=%s' % tmp_path)
    assert script.returncode == 0, output[-6000:]
    assert 'slurm_campaign: OK:' in output
    assert not left, 'processes of the test cluster still running: %s' % left
    directory = re.search(r'^slurm_campaign: cluster directory (\S+)$', output, re.M)
    assert directory and not os.path.exists(directory.group(1)), 'cluster directory left'

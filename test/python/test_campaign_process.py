"""pd_campaign.campaign_process: a campaign forked from the pre-imported server is the campaign
the command runs: the same outputs, exit statuses and Ctrl-C."""
import csv
import filecmp
import os
import signal
import subprocess
import time

from pd_campaign import campaign_process

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
ARGS = ['--scenario', os.path.join(ROOT, 'config', 'scenario_paper.yaml'), '--rpm', '12000',
        '--jobs', '1', '--seed', '33', '--no-figures']


def test_a_forked_campaign_writes_what_the_command_writes(tmp_path):
    log = tmp_path / 'forked.log'
    log.write_text('')
    status = campaign_process.run(ARGS + ['--trials', '1', '--out', str(tmp_path / 'forked')],
                                  str(log))
    assert status == 0, log.read_text()[-3000:]
    assert 'campaign: 3/3 trials finished' in log.read_text()
    command = subprocess.run(['rosrun', 'pedicle_drilling', 'campaign'] + ARGS +
                             ['--trials', '1', '--out', str(tmp_path / 'command')],
                             capture_output=True, text=True, timeout=600)
    assert command.returncode == 0, command.stderr[-3000:]
    for name in ('trials.csv', 'summary.json', 'report.md'):
        assert filecmp.cmp(tmp_path / 'forked' / name, tmp_path / 'command' / name,
                           shallow=False), name


def test_a_refusal_is_exit_2_with_the_campaigns_message_in_the_log(tmp_path):
    log = tmp_path / 'refused.log'
    log.write_text('earlier line\n')
    status = campaign_process.run(ARGS + ['--trials', '1', '--seed', '-1',
                                          '--out', str(tmp_path / 'out')], str(log))
    assert status == 2
    text = log.read_text()
    assert text.startswith('earlier line\n'), 'the log is appended to, as the caller made it'
    assert 'campaign: ' in text and '--seed' in text
    assert not (tmp_path / 'out' / 'trials.csv').exists()


def test_ctrl_c_stops_it_with_exit_130_keeping_the_finished_trials(tmp_path):
    log = tmp_path / 'stopped.log'
    log.write_text('')
    out = tmp_path / 'out'
    process = campaign_process.CampaignProcess(ARGS + ['--trials', '40', '--out', str(out)],
                                               str(log))

    def finished_rows():
        try:
            with open(out / 'trials.csv') as handle:
                return len(list(csv.DictReader(handle)))
        except OSError:
            return 0

    deadline = time.monotonic() + 300.0  # a bound on a broken run, not a pacing
    while finished_rows() < 1:
        assert time.monotonic() < deadline, log.read_text()[-3000:]
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)
    assert process.wait() == 130, log.read_text()[-3000:]
    assert 'interrupted; stopping workers, keeping finished trials' in log.read_text()
    assert 1 <= finished_rows() < 120

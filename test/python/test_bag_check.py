"""A kept recording says what it lost: pd_campaign.bags.check_bag counts every
topic of a campaign bag, names the required topics that have no message and finds the samples
missing from the force stream (gaps against its own median period). Checked on bags written
here, with known losses. And the worker names a dead process of its launch from roslaunch's log
(worker.died_processes)."""

import pytest


rosbag = pytest.importorskip('rosbag')
import rospy  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402

from pd_campaign import bags, worker  # noqa: E402


def write_bag(path, force_times, topics=()):
    with rosbag.Bag(str(path), 'w') as bag:  # not atomic: a test fixture
        for t in force_times:
            msg = WrenchStamped()
            msg.header.stamp = rospy.Time.from_sec(t)
            bag.write('/ft_sensor/wrench', msg, msg.header.stamp)
        for topic in topics:
            bag.write(topic, DiagnosticArray(), rospy.Time.from_sec(1.0))


def test_a_complete_force_stream_loses_nothing_but_silent_required_topics_are_named(tmp_path):
    path = tmp_path / 'complete.bag'
    write_bag(path, [1.0 + 1e-3 * i for i in range(2000)], topics=['/diagnostics'])
    check = bags.check_bag(str(path))
    assert check['force_samples'] == 2000
    assert check['force_samples_lost'] == 0 and check['force_gaps'] == []
    assert check['messages']['/diagnostics'] == 1
    assert '/diagnostics' not in check['missing_topics']
    assert '/simulator/ground_truth' in check['missing_topics']
    assert not check['complete']
    assert 'no message on' in check['summary'] and 'force samples lost' not in check['summary']


def test_dropped_force_samples_are_counted_with_the_longest_gap(tmp_path):
    times = [1.0 + 1e-3 * i for i in range(3000)]
    kept = [t for i, t in enumerate(times) if not 1000 <= i < 1150 and i != 2000]  # 151 lost
    path = tmp_path / 'gaps.bag'
    write_bag(path, kept)
    check = bags.check_bag(str(path))
    assert check['force_samples'] == 3000 - 151
    assert check['force_samples_lost'] == 151
    assert len(check['force_gaps']) == 2
    assert abs(max(g['dt_s'] for g in check['force_gaps']) - 0.151) < 1e-6
    assert '151 force samples lost in 2 gaps (longest 151 ms' in check['summary']


def test_the_period_is_the_streams_own_so_the_default_daq_rate_loses_nothing(tmp_path):
    """The Simulator's default DAQ runs at 1000/3 Hz (every 3 ms): a complete stream at that
    rate loses nothing, and a gap of 30 ms there is 9 samples, not 29."""
    times = [1.0 + 3e-3 * i for i in range(1000)]
    path = tmp_path / 'daq.bag'
    write_bag(path, times)
    assert bags.check_bag(str(path))['force_samples_lost'] == 0
    kept = [t for i, t in enumerate(times) if not 500 <= i < 509]
    path = tmp_path / 'daq_gap.bag'
    write_bag(path, kept)
    check = bags.check_bag(str(path))
    assert check['force_samples_lost'] == 9 and len(check['force_gaps']) == 1


def test_every_required_topic_is_recorded():
    assert set(bags.BAG_REQUIRED) <= set(bags.BAG_TOPICS)
    for topic in ('/spindle/command', '/ventilator/settings', '/diagnostics'):
        assert topic in bags.BAG_REQUIRED
    assert '/clock' not in bags.BAG_TOPICS  # rosbag play --clock makes the clock


def test_a_dead_process_of_the_launch_is_named_from_roslaunchs_log(tmp_path):
    """A crash of the nodelet manager ends every service call with a transport error; the
    worker names the dead process from roslaunch's own lines (children.log)."""
    log = tmp_path / 'children.log'
    log.write_text(
        '... logging to /tmp/x/roslaunch.log\n'
        'process[pedicle_drilling_manager-1]: started with pid [4242]\n'
        '[pedicle_drilling_manager-1] process has died [pid 4242, exit code -11, cmd '
        '/usr/lib/nodelet/nodelet manager __name:=pedicle_drilling_manager].\n'
        'log file: /tmp/x/pedicle_drilling_manager-1*.log\n')
    died = worker.died_processes(str(log))
    assert len(died) == 1 and 'exit code -11' in died[0], died
    assert worker.died_processes(str(tmp_path / 'missing.log')) == []

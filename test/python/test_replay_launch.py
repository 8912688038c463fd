"""replay.launch: a campaign-style bag played on sim time from the bag, headless: the
clock it publishes never steps back, every force sample comes out with its stamp, and
robot_description is set for the workcell display (a bag cannot hold it)."""
import os
import subprocess
import sys
import textwrap

import pytest

rosbag = pytest.importorskip('rosbag')
import rospy  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402

PORT = 11611

LISTENER = textwrap.dedent('''
    import sys, rospy
    from rosgraph_msgs.msg import Clock
    from geometry_msgs.msg import WrenchStamped
    clocks, stamps = [], []
    rospy.init_node('replay_listener', disable_signals=True)
    rospy.Subscriber('/clock', Clock, lambda m: clocks.append(m.clock.to_sec()), queue_size=5000)
    rospy.Subscriber('/ft_sensor/wrench', WrenchStamped,
                     lambda m: stamps.append(m.header.stamp.to_sec()), queue_size=5000)
    import time
    deadline = time.time() + 60
    while time.time() < deadline and len(stamps) < int(sys.argv[1]):
        time.sleep(0.05)
    urdf = rospy.get_param('/robot_description', '')
    back = sum(1 for a, b in zip(clocks, clocks[1:]) if b < a)
    print('%d %d %d %d' % (len(stamps), len(clocks), back, 'rsssii_joint1' in urdf))
''')


def _wait_for_master(launch, uri, deadline_s=120.0):
    """Waits until the launch's master answers at `uri` (the launch still running)."""
    import time
    import rosgraph
    master = rosgraph.Master('/replay_test', master_uri=uri)
    deadline = time.monotonic() + deadline_s  # a bound on a broken run, not a pacing
    while True:
        assert launch.poll() is None, 'roslaunch ended with %s' % launch.returncode
        try:
            master.getPid()
            return
        except Exception:  # noqa: BLE001 (refused until the master listens)
            assert time.monotonic() < deadline, 'no master at %s' % uri
            time.sleep(0.05)


def test_a_bag_replays_on_its_own_clock(tmp_path):
    bag_path = tmp_path / 'trial.bag'
    n = 1500
    with rosbag.Bag(str(bag_path), 'w') as bag:  # not atomic: a test fixture
        for i in range(n):
            msg = WrenchStamped()
            msg.header.stamp = rospy.Time.from_sec(100.0 + 1e-3 * i)
            bag.write('/ft_sensor/wrench', msg, msg.header.stamp)
    env = dict(os.environ, ROS_MASTER_URI='http://127.0.0.1:%d' % PORT)
    launch = subprocess.Popen(
        ['roslaunch', '-p', str(PORT), 'pedicle_drilling', 'replay.launch',
         'bag:=%s' % bag_path, 'headless:=true', 'start_s:=0.0', 'rate:=1.0',
         'wait_for_subscribers:=true'],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        _wait_for_master(launch, env['ROS_MASTER_URI'])
        # Nothing is played before the listener subscribed (wait_for_subscribers): all samples.
        out = subprocess.run(['/usr/bin/python3', '-c', LISTENER, str(n)], env=env,
                             capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr[-2000:]
        stamps, clocks, back, has_urdf = (int(v) for v in out.stdout.split()[-4:])
        assert stamps == n, out.stdout
        assert clocks > 10 and back == 0, out.stdout
        assert has_urdf == 1
    finally:
        import signal
        os.killpg(launch.pid, signal.SIGINT)
        try:
            launch.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(launch.pid, signal.SIGKILL)

"""Loopback by default: every shipped launch file starts its nodes with ROS_HOSTNAME
(and, on loopback, ROS_IP) set to its `ros_host` argument, 127.0.0.1 unless the user exported
ROS_HOSTNAME or ROS_IP or gave ros_host:=...; and a launched nodelet manager really serves its
topics on 127.0.0.1 only."""
import glob
import os
import signal
import socket
import subprocess
import time
import xml.etree.ElementTree as ET
import xmlrpc.client

import pytest
from roslaunch.config import ROSLaunchConfig
from roslaunch.xmlloader import XmlLoader

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
from shipped_docs import required_launch_args  # noqa: E402
LAUNCH_FILES = sorted(glob.glob(os.path.join(ROOT, 'launch_scripts', '*.launch')))


def node_environments(path, argv=(), **environment):
    """{node name: the environment variables roslaunch sets for it} for `path` loaded with
    `argv` (name:=value) in a shell that exported `environment` (ROS_IP / ROS_HOSTNAME)."""
    saved = {k: os.environ.get(k) for k in ('ROS_IP', 'ROS_HOSTNAME')}
    try:
        for key in saved:
            os.environ.pop(key, None)
        os.environ.update(environment)
        config = ROSLaunchConfig()
        XmlLoader().load(path, config, argv=list(argv), verbose=False)
    finally:
        for key, value in saved.items():
            os.environ.pop(key, None)
            if value is not None:
                os.environ[key] = value
    nodes = config.nodes
    assert nodes, '%s starts no node' % path
    return {node.namespace + node.name: dict(node.env_args) for node in nodes}


def cases():
    return [(path, required_launch_args(path)) for path in LAUNCH_FILES] + [
        (os.path.join(ROOT, 'launch_scripts', 'drilling_pipeline.launch'), ['sim:=true'])]


def case_id(case):
    path, argv = case
    return os.path.basename(path) + ''.join(' ' + a for a in argv)


@pytest.mark.parametrize('case', cases(), ids=case_id)
def test_every_node_of_a_launch_binds_to_loopback_by_default(case):
    path, argv = case
    for name, env in node_environments(path, argv).items():
        assert env.get('ROS_HOSTNAME') == '127.0.0.1', (name, env)
        assert env.get('ROS_IP') == '127.0.0.1', (name, env)


@pytest.mark.parametrize('case', cases(), ids=case_id)
def test_an_exported_address_is_kept_for_a_multi_machine_setup(case):
    path, argv = case
    # ROS_IP alone: the nodes use it (ROS_HOSTNAME set to the same address, ROS_IP untouched).
    for name, env in node_environments(path, argv, ROS_IP='192.0.2.10').items():
        assert env.get('ROS_HOSTNAME') == '192.0.2.10', (name, env)
        assert 'ROS_IP' not in env, (name, env)
    # ROS_HOSTNAME wins over ROS_IP, as in ROS itself.
    for name, env in node_environments(path, argv, ROS_HOSTNAME='robot.example',
                                       ROS_IP='192.0.2.10').items():
        assert env.get('ROS_HOSTNAME') == 'robot.example', (name, env)
        assert 'ROS_IP' not in env, (name, env)
    # An exported loopback address keeps the nodes on loopback, roscpp's topics too.
    for name, env in node_environments(path, argv, ROS_HOSTNAME='localhost').items():
        assert (env.get('ROS_HOSTNAME'), env.get('ROS_IP')) == ('localhost', '127.0.0.1'), name


@pytest.mark.parametrize('case', cases(), ids=case_id)
def test_the_ros_host_argument_opens_or_closes_it_deliberately(case):
    path, argv = case
    # Given on the command line, it reaches every node, through every include.
    for name, env in node_environments(path, list(argv) + ['ros_host:=192.0.2.10']).items():
        assert env.get('ROS_HOSTNAME') == '192.0.2.10', (name, env)
        assert 'ROS_IP' not in env, (name, env)
    for name, env in node_environments(path, list(argv) + ['ros_host:=127.0.0.1'],
                                       ROS_HOSTNAME='robot.example').items():
        assert (env.get('ROS_HOSTNAME'), env.get('ROS_IP')) == ('127.0.0.1', '127.0.0.1'), name


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=os.path.basename)
def test_the_network_settings_come_before_every_node_and_reach_every_include(path):
    launch = ET.parse(path).getroot()
    tags = [child.tag for child in launch]
    envs = [i for i, child in enumerate(launch) if child.tag == 'env']
    assert sorted(child.get('name') for child in launch if child.tag == 'env') == \
        ['ROS_HOSTNAME', 'ROS_IP']
    assert all(i < tags.index(tag) for i in envs for tag in ('node', 'include') if tag in tags)
    for include in launch.iter('include'):
        assert 'ros_host' in [a.get('name') for a in include.findall('arg')], \
            include.get('file')


# --- a launched nodelet manager -----------------------------------------------------------------

def _free_port():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def listening_sockets(pid):
    """(address, port) of every listening TCP socket of process `pid`."""
    inodes = set()
    fd_dir = '/proc/%d/fd' % pid
    for fd in os.listdir(fd_dir):
        try:
            target = os.readlink(os.path.join(fd_dir, fd))
        except OSError:
            continue
        if target.startswith('socket:['):
            inodes.add(target[8:-1])
    found = []
    for table, width in (('/proc/net/tcp', 8), ('/proc/net/tcp6', 32)):
        with open(table) as handle:
            next(handle)
            for line in handle:
                fields = line.split()
                local, state, inode = fields[1], fields[3], fields[9]
                if state != '0A' or inode not in inodes:  # 0A: LISTEN
                    continue
                address, port = local.split(':')
                raw = bytes.fromhex(address)
                if width == 8:
                    host = socket.inet_ntop(socket.AF_INET, raw[::-1])
                else:  # four host-order 32-bit words
                    host = socket.inet_ntop(socket.AF_INET6, b''.join(
                        raw[i:i + 4][::-1] for i in range(0, 16, 4)))
                found.append((host, int(port, 16)))
    return found


def _stop(process):
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGINT)
        try:
            process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()


def test_a_launched_nodelet_manager_serves_its_topics_on_loopback_only(tmp_path):
    port = _free_port()
    master_uri = 'http://127.0.0.1:%d' % port
    env = {k: v for k, v in os.environ.items() if k not in ('ROS_IP', 'ROS_HOSTNAME')}
    env.update(ROS_MASTER_URI=master_uri, ROS_LOG_DIR=str(tmp_path / 'log'))
    # The master as doc/network.md says to start it on loopback; the launch itself in a shell that
    # exported neither ROS_IP nor ROS_HOSTNAME.
    master = subprocess.Popen(['rosmaster', '--core', '-p', str(port), '-w', '2'],
                              env=dict(env, ROS_IP='127.0.0.1'), stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, start_new_session=True)
    launch = None
    try:
        proxy = xmlrpc.client.ServerProxy(master_uri)
        deadline = time.time() + 60
        while True:
            try:
                proxy.getPid('/test')
                break
            except OSError:
                assert time.time() < deadline, 'the master did not start'
                time.sleep(0.1)
        launch = subprocess.Popen(['roslaunch', 'pedicle_drilling', 'ventilator.launch'],
                                  env=env, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL, start_new_session=True)
        # Wait for the event: the ventilator's tidal_volume publisher registered.
        while True:
            _, _, state = proxy.getSystemState('/test')
            publishers = dict((topic, nodes) for topic, nodes in state[0])
            if '/pedicle_drilling_manager' in publishers.get('/tidal_volume', []):
                break
            assert launch.poll() is None, 'roslaunch exited with %s' % launch.returncode
            assert time.time() < deadline, 'the ventilator did not advertise tidal_volume'
            time.sleep(0.1)
        code, _, node_uri = proxy.lookupNode('/test', '/pedicle_drilling_manager')
        assert code == 1
        assert node_uri.startswith('http://127.0.0.1:'), node_uri
        node = xmlrpc.client.ServerProxy(node_uri)
        code, _, (protocol, host, tcpros_port) = node.requestTopic(
            '/test', '/tidal_volume', [['TCPROS']])
        assert (code, protocol, host) == (1, 'TCPROS', '127.0.0.1')
        _, _, pid = node.getPid('/test')
        sockets = listening_sockets(pid)
        xmlrpc_port = int(node_uri.rstrip('/').rsplit(':', 1)[1])
        assert ('127.0.0.1', tcpros_port) in sockets, sockets
        # roscpp's XML-RPC server (xmlrpcpp) binds every interface whatever ROS_IP says (doc/network.md);
        # everything else of the process, its topics and services, listens on loopback only.
        others = [s for s in sockets if s[1] != xmlrpc_port]
        assert others and all(h == '127.0.0.1' for h, _ in others), sockets
    finally:
        if launch is not None:
            _stop(launch)
        _stop(master)

"""The launch argument drilling_target (pose or plan) sets the CompensationPlanner's
~target_from_plan; any other value reaches the planner as a text naming the argument and its
values, which the planner refuses at load ("parameter .../target_from_plan must be true or
false"), so a typo fails the launch instead of drilling from the configured pose. Read from
roslaunch's own loader (--dump-params: no master, nothing started)."""
import subprocess

import pytest
import yaml


def planner_target(launch, *args):
    out = subprocess.run(['roslaunch', '--dump-params', 'pedicle_drilling', launch] + list(args),
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr + out.stdout
    return yaml.safe_load(out.stdout)['/compensation_planner/target_from_plan']


@pytest.mark.parametrize('launch', ['compensation_planner.launch', 'hardware.launch'])
def test_pose_and_plan_set_the_planners_bool(launch):
    assert planner_target(launch) is False
    assert planner_target(launch, 'drilling_target:=pose') is False
    assert planner_target(launch, 'drilling_target:=plan') is True


def test_another_value_reaches_the_planner_naming_the_argument():
    value = planner_target('hardware.launch', 'drilling_target:=plna')
    assert value == 'drilling_target must be pose or plan, not plna'

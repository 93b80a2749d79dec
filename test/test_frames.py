"""The frame chain the node puts on /tf (core.frames), without ROS.

Reference: composing the links as 3x3 homogeneous matrices (numpy, not the module's own
arithmetic) must put every top-chord frame at A4 with its x-axis through A3, and the head
at the top chord's midpoint with the head_pose angle, for one module and a neck.
"""
import math
from pathlib import Path

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest

from tensegrity_ros.core import ModuleParams
from tensegrity_ros.core.neck.frames import chord_frames, PlanarTransform
from tensegrity_ros.core.simulation.simulator import Simulator
from tensegrity_ros.params_file import load_stack_config

ROOT = Path(__file__).resolve().parents[1]


def matrix(link):
    c, s = math.cos(link.yaw), math.sin(link.yaw)
    return np.array([[c, -s, link.x], [s, c, link.y], [0.0, 0.0, 1.0]])


def composed(links):
    """The base-frame pose matrix of every frame of the chain."""
    out, pose = [], np.eye(3)
    for link in links:
        pose = pose @ matrix(link)
        out.append(pose)
    return out


def check_chain(sim):
    nodes = [sim.module_nodes(i) for i in range(len(sim))]
    links = chord_frames(nodes)
    assert len(links) == len(sim) + 1
    poses = composed(links)
    for pose, (a1, a2, a3, a4) in zip(poses, nodes):
        np.testing.assert_allclose(pose[:2, 2], a4, atol=1e-12)
        direction = (a3 - a4) / np.linalg.norm(a3 - a4)
        np.testing.assert_allclose(pose[:2, 0], direction, atol=1e-12)
    position, angle = sim.head()
    np.testing.assert_allclose(poses[-1][:2, 2], position, atol=1e-12)
    assert math.atan2(poses[-1][1, 0], poses[-1][0, 0]) == pytest.approx(angle, abs=1e-12)
    for link in links:
        assert -math.pi < link.yaw <= math.pi
        q = np.array(link.quaternion)
        assert np.linalg.norm(q) == pytest.approx(1.0)
        assert 2 * math.atan2(q[2], q[3]) == pytest.approx(link.yaw, abs=1e-12)


@given(st.floats(0.2, 1.6), st.sampled_from([[0.7, 0.7], [-1.0, -1.0]]),
       st.floats(-5.0, 5.0))
@settings(max_examples=25, deadline=None)
def test_one_module_chain_reaches_the_top_chord_and_the_head(rho, guess, force):
    sim = Simulator([ModuleParams.paper(rho, F3=force, F4=force)], [guess], time_budget=None)
    check_chain(sim)


def test_the_neck_chain_stacks_each_module_on_the_chord_below():
    config = load_stack_config(ROOT / 'config' / 'neck.yaml')
    sim = Simulator([m.params for m in config.modules], config.initial_theta,
                    names=config.names, time_budget=None)
    check_chain(sim)
    links = chord_frames([sim.module_nodes(i) for i in range(len(sim))])
    # module i+1's base is module i's chord frame: its A1 at the origin, A2 on the x-axis
    poses = composed(links)
    for i in range(1, len(sim)):
        a1, a2 = sim.module_nodes(i)[:2]
        local = np.linalg.inv(poses[i - 1]) @ np.array([[*a1, 1.0], [*a2, 1.0]]).T
        np.testing.assert_allclose(local[:2, 0], [0.0, 0.0], atol=1e-12)
        assert local[1, 1] == pytest.approx(0.0, abs=1e-12)
        assert local[0, 1] == pytest.approx(sim.modules[i].rho, abs=1e-12)


def test_a_level_chord_is_a_pure_translation_and_the_head_half_the_chord():
    nodes = np.array([[0.0, 0.0], [1.0, 0.0], [0.75, 0.5], [0.25, 0.5]])
    first, head = chord_frames([nodes])
    assert first == PlanarTransform(0.25, 0.5, 0.0)
    assert head == PlanarTransform(0.25, 0.0, 0.0)

#!/usr/bin/env python3
"""orca3d_server through ROS: real service calls against the numpy reference.

Runs in orca3d_server.test next to the node, which has non-default parameters
(timeHorizon 4.0, ~max_neighbors 50, ~max_agents 200). Every answer is compared with
magna_orca_cpp.reference on the same input; refusals must name the bad field, and the
node must keep answering after them. The command line (--help, unknown arguments, bad
parameters, remapped service names) is checked on extra node processes this test starts
and ends itself.
"""
import copy
import math
import signal
import subprocess
import unittest

import numpy as np
import roslib.packages
import rospy
import rostest
from geometry_msgs.msg import Point, Vector3
from magna_msgs.msg import OrcaAgent, OrcaParams
from magna_msgs.srv import (
    OrcaComputeVelocities,
    OrcaComputeVelocitiesRequest,
    OrcaComputeVelocity,
    OrcaComputeVelocityRequest,
)

from magna_orca_cpp import model, reference

NODE = "/orca3d_server"  # as named in launch/orca3d.launch
ONE = "/magna/orca3d/compute_velocity"
BATCH = "/magna/orca3d/compute_velocities"
TOLERANCE = 1e-6
# Explicit request parameters, all different from the server's.
REQUEST_PARAMS = model.Params(max_neighbors=6, time_step=0.1, neighbor_dist=5.0, time_horizon=3.0,
                              agent_radius=0.5, max_speed=2.0)


def agent_msg(agent_id, position, velocity=(0, 0, 0), preferred=(0, 0, 0), radius=0.0, max_speed=0.0,
              cooperative=True):
    return OrcaAgent(id=agent_id, position=Point(*map(float, position)), velocity=Vector3(*map(float, velocity)),
                     preferred_velocity=Vector3(*map(float, preferred)), radius=float(radius),
                     max_speed=float(max_speed), non_cooperative=not cooperative)


def to_model(msg):
    p, v, w = msg.position, msg.velocity, msg.preferred_velocity
    return model.Agent([p.x, p.y, p.z], [v.x, v.y, v.z], [w.x, w.y, w.z], msg.radius, msg.max_speed,
                       not msg.non_cooperative)


def params_msg(params):
    return OrcaParams(n_neighbors_aware=params.max_neighbors, time_step=params.time_step,
                      neighbor_dist=params.neighbor_dist, time_horizon=params.time_horizon,
                      agent_radius=params.agent_radius, max_speed=params.max_speed)


def vector(msg):
    return np.array([msg.x, msg.y, msg.z])


def server_params():
    """The solver parameters the node was started with, read back from the parameter server."""
    values = rospy.get_param(NODE)
    return model.Params.from_algorithm_control({k: v for k, v in values.items() if k in model.ALGORITHM_CONTROL_NAMES})


def scenarios():
    """(name, agent, neighbours): a head-on pair, a crowd with an obstacle, overlaps, a boxed-in agent."""
    head_on = (agent_msg(1, (0, 0, 5), (1, 0, 0), (1, 0, 0)),
               [agent_msg(2, (4, 0, 5), (-1, 0, 0), (-1, 0, 0))])
    crowd = (agent_msg(3, (0, 0, 2), (1.5, 0, 0), (2, 0, 0), radius=0.4),
             [agent_msg(10, (3, 0.5, 2), (-1, 0, 0), (-1, 0, 0)),  # radius 0: takes params.agent_radius
              agent_msg(11, (1, 2, 2.3), (0, -1, 0), (0, -1, 0), radius=0.3, max_speed=1.0),
              agent_msg(12, (2, -1, 2), radius=0.8, cooperative=False),  # a static obstacle
              agent_msg(13, (-2, 0.5, 1.5), (1.2, 0, 0.1), (1.5, 0, 0), radius=0.5),
              agent_msg(14, (1.5, 0.2, 3.5), (0, 0, -1), (0, 0, -1), radius=0.45, max_speed=3.0),
              agent_msg(15, (30, 0, 2), (-2, 0, 0), (-2, 0, 0))])  # beyond neighborDist
    rng = np.random.default_rng(11)
    many = (agent_msg(4, (0, 0, 0), (0.5, 0.5, 0), (1, 1, 0), radius=0.5),
            [agent_msg(20 + k, rng.uniform(-4, 4, 3), rng.normal(0, 1, 3), rng.normal(0, 1, 3),
                       radius=rng.uniform(0.2, 0.7), max_speed=rng.uniform(1, 3), cooperative=k % 4 != 0)
             for k in range(12)])  # more than N_neighbors_aware
    overlap = (agent_msg(5, (0, 0, 0), (0.2, 0, 0), (1, 0, 0), radius=0.5),
               [agent_msg(30, (0.8, 0.1, 0), (-0.2, 0, 0), (-1, 0, 0), radius=0.5)])
    boxed = (agent_msg(6, (0, 0, 0), (0, 0, 0), (1, 0, 0), radius=0.5, max_speed=0.5),
             [agent_msg(40, (0.9, 0, 0), radius=0.5, cooperative=False),
              agent_msg(41, (-0.9, 0, 0), radius=0.5, cooperative=False)])
    stubborn = (agent_msg(7, (0, 0, 0), (1, 0, 0), (1, 0, 0), cooperative=False),
                [agent_msg(50, (2, 0, 0), (-1, 0, 0), (-1, 0, 0))])
    return {"head_on": head_on, "crowd": crowd, "many": many, "overlap": overlap, "boxed": boxed,
            "non_cooperative_self": stubborn}


def random_batch(seed, count=20):
    rng = np.random.default_rng(seed)
    ids = rng.permutation(1000)[:count]
    agents = []
    for k in range(count):
        position = rng.uniform([-5, -5, 0], [5, 5, 4])
        goal = rng.uniform([-5, -5, 0], [5, 5, 4])
        preferred = (goal - position) / max(1.0, np.linalg.norm(goal - position) / 2.0)
        agents.append(agent_msg(int(ids[k]), position, rng.normal(0, 1, 3), preferred,
                                radius=rng.choice([0.0, 0.3, 0.5, 0.7]), max_speed=rng.choice([0.0, 1.5, 2.5]),
                                cooperative=k % 7 != 3))
    return agents


def node_binary():
    found = roslib.packages.find_node("magna_orca_cpp", "orca3d_server")
    if not found:
        raise AssertionError("orca3d_server is not built: run catkin build magna_orca_cpp")
    return found[0]


def run_node(*args, timeout=30.0):
    """Runs the node to its end; (exit status, stdout + stderr)."""
    process = subprocess.Popen([node_binary(), *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        output, _ = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        process.communicate()
        raise AssertionError(f"orca3d_server {' '.join(args)} did not exit within {timeout} s") from None
    return process.returncode, output


class Orca3dServerTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("orca3d_server_test")
        rospy.wait_for_service(ONE, timeout=30)
        rospy.wait_for_service(BATCH, timeout=30)
        cls.one = rospy.ServiceProxy(ONE, OrcaComputeVelocity)
        cls.batch = rospy.ServiceProxy(BATCH, OrcaComputeVelocities)
        cls.server = server_params()

    def solve_one(self, agent, neighbors, params):
        request = OrcaComputeVelocityRequest(agent=agent, neighbors=neighbors, params=params)
        return self.one(request)

    def assert_matches_reference(self, response, agent, neighbors, params, what):
        expected = reference.new_velocity(to_model(agent), [to_model(n) for n in neighbors], params)
        self.assertTrue(response.success, f"{what}: {response.message}")
        np.testing.assert_allclose(vector(response.velocity), expected.velocity, rtol=0, atol=TOLERANCE,
                                   err_msg=what)
        self.assertEqual(response.feasible, expected.feasible, what)
        return expected

    def test_1_one_shot_matches_the_reference(self):
        self.assertEqual(self.server.time_horizon, 4.0, "orca3d_server.test sets ~timeHorizon 4.0")
        feasible = {}
        for name, (agent, neighbors) in scenarios().items():
            for params in (REQUEST_PARAMS, self.server):
                response = self.solve_one(agent, neighbors, params_msg(params))
                expected = self.assert_matches_reference(response, agent, neighbors, params, name)
                feasible[name] = expected.feasible
                self.assertTrue(response.message.startswith("ok: agent"), response.message)
        # The scenarios do reach avoidance and the infeasible fallback.
        head_on, neighbors = scenarios()["head_on"]
        response = self.solve_one(head_on, neighbors, params_msg(REQUEST_PARAMS))
        self.assertGreater(np.linalg.norm(vector(response.velocity) - vector(head_on.preferred_velocity)), 0.1)
        self.assertFalse(feasible["boxed"])
        self.assertTrue(feasible["head_on"])
        self.assertIn("non-cooperative", self.solve_one(*scenarios()["non_cooperative_self"],
                                                         params_msg(REQUEST_PARAMS)).message)

    def test_2_all_zero_params_take_the_servers(self):
        # Two agents closing slowly: the new velocity depends on the time horizon.
        agent = agent_msg(1, (0, 0, 1), (0.275, 0, 0), (0.275, 0, 0))
        neighbors = [agent_msg(2, (3, 0, 1), (-0.275, 0, 0), (-0.275, 0, 0))]
        response = self.solve_one(agent, neighbors, OrcaParams())
        self.assert_matches_reference(response, agent, neighbors, self.server, "all-zero params")
        self.assertIn("server parameters", response.message)
        other = copy.copy(self.server)
        other.time_horizon = 5.0
        with_five = reference.new_velocity(to_model(agent), [to_model(n) for n in neighbors], other)
        self.assertGreater(np.linalg.norm(vector(response.velocity) - with_five.velocity), 1e-3,
                           "the scenario must tell timeHorizon 4 from 5")
        # The same block sent explicitly gives the same answer.
        explicit = self.solve_one(agent, neighbors, params_msg(self.server))
        np.testing.assert_allclose(vector(explicit.velocity), vector(response.velocity), rtol=0, atol=1e-12)
        self.assertIn("request parameters", explicit.message)

    def test_3_batch_matches_the_reference_in_order(self):
        agents = random_batch(seed=2024)
        for params, block in ((REQUEST_PARAMS, params_msg(REQUEST_PARAMS)), (self.server, OrcaParams())):
            response = self.batch(OrcaComputeVelocitiesRequest(agents=agents, params=block))
            self.assertTrue(response.success, response.message)
            expected = reference.new_velocities([to_model(a) for a in agents], params)
            self.assertEqual(len(response.velocities), len(agents))
            self.assertEqual(len(response.feasible), len(agents))
            got = np.array([vector(v) for v in response.velocities])
            np.testing.assert_allclose(got, np.array([s.velocity for s in expected]), rtol=0, atol=TOLERANCE)
            self.assertEqual(list(response.feasible), [s.feasible for s in expected])
            preferred = np.array([vector(a.preferred_velocity) for a in agents])
            self.assertGreater(int(np.sum(np.linalg.norm(got - preferred, axis=1) > 1e-3)), 0,
                               "some agents must have had to avoid")
        empty = self.batch(OrcaComputeVelocitiesRequest(agents=[], params=OrcaParams()))
        self.assertTrue(empty.success, empty.message)
        self.assertEqual(list(empty.velocities), [])

    def bad_one_shot_requests(self):
        """(expected text, request) pairs, each with one fault in a good request."""
        agent, neighbors = scenarios()["crowd"]
        good = OrcaComputeVelocityRequest(agent=agent, neighbors=neighbors, params=params_msg(REQUEST_PARAMS))
        cases = []

        def case(expected, change):
            request = copy.deepcopy(good)
            change(request)
            cases.append((expected, request))

        case("agent.position.x is nan", lambda r: setattr(r.agent.position, "x", math.nan))
        case("neighbors[1].velocity.y is inf", lambda r: setattr(r.neighbors[1].velocity, "y", math.inf))
        case("neighbors[2].preferred_velocity.z is -inf",
             lambda r: setattr(r.neighbors[2].preferred_velocity, "z", -math.inf))
        case("neighbors[3].radius is -1", lambda r: setattr(r.neighbors[3], "radius", -1.0))
        case("agent.max_speed is nan", lambda r: setattr(r.agent, "max_speed", math.nan))
        case("params.time_step (timeStep) is nan", lambda r: setattr(r.params, "time_step", math.nan))
        case("params.time_horizon (timeHorizon) is 0", lambda r: setattr(r.params, "time_horizon", 0.0))
        case("params.neighbor_dist (neighborDist) is inf", lambda r: setattr(r.params, "neighbor_dist", math.inf))
        case("params.agent_radius is -0.5", lambda r: setattr(r.params, "agent_radius", -0.5))
        case("params.n_neighbors_aware (N_neighbors_aware) is 51",
             lambda r: setattr(r.params, "n_neighbors_aware", 51))
        case("neighbors has 51 entries", lambda r: setattr(
            r, "neighbors", [agent_msg(100 + k, (k + 1.0, 0, 0)) for k in range(51)]))
        case("neighbors[2].id 3 repeats agent.id", lambda r: setattr(r.neighbors[2], "id", r.agent.id))
        case("neighbors[4].id 10 repeats neighbors[0].id", lambda r: setattr(r.neighbors[4], "id", 10))
        case("agent.radius is 0 and params.agent_radius is 0", lambda r: (
            setattr(r.agent, "radius", 0.0), setattr(r.params, "agent_radius", 0.0)))
        return cases

    def bad_batch_requests(self):
        agents = random_batch(seed=5)
        good = OrcaComputeVelocitiesRequest(agents=agents, params=OrcaParams())
        cases = []

        def case(expected, change):
            request = copy.deepcopy(good)
            change(request)
            cases.append((expected, request))

        case("agents has 201 entries", lambda r: setattr(
            r, "agents", [agent_msg(k, (k, 0, 0)) for k in range(201)]))
        def repeat_seven(request):
            for k, agent in enumerate(request.agents):
                agent.id = 7 if k in (1, 4) else 100 + k

        case("agents[4].id 7 repeats agents[1].id", repeat_seven)
        case("agents[5].position.z is nan", lambda r: setattr(r.agents[5].position, "z", math.nan))
        case("agents[2].radius is -1", lambda r: setattr(r.agents[2], "radius", -1.0))
        case("agents[0].velocity.x is -inf", lambda r: setattr(r.agents[0].velocity, "x", -math.inf))
        case("params.time_horizon (timeHorizon) is 0", lambda r: (
            setattr(r, "params", params_msg(REQUEST_PARAMS)), setattr(r.params, "time_horizon", 0.0)))
        case("params.n_neighbors_aware (N_neighbors_aware) is 1000", lambda r: (
            setattr(r, "params", params_msg(REQUEST_PARAMS)), setattr(r.params, "n_neighbors_aware", 1000)))
        return cases

    def test_4_bad_input_is_refused_by_name_and_the_node_survives(self):
        for expected, request in self.bad_one_shot_requests():
            response = self.one(request)
            rospy.loginfo("compute_velocity refused: %s", response.message)
            self.assertFalse(response.success, expected)
            self.assertIn(expected, response.message)
            self.assertFalse(response.feasible)
        for expected, request in self.bad_batch_requests():
            response = self.batch(request)
            rospy.loginfo("compute_velocities refused: %s", response.message)
            self.assertFalse(response.success, expected)
            self.assertIn(expected, response.message)
            self.assertEqual(list(response.velocities), [])
        # Still alive and still right.
        agent, neighbors = scenarios()["crowd"]
        response = self.solve_one(agent, neighbors, params_msg(REQUEST_PARAMS))
        self.assert_matches_reference(response, agent, neighbors, REQUEST_PARAMS, "after the refusals")
        self.assertTrue(self.batch(OrcaComputeVelocitiesRequest(agents=random_batch(3), params=OrcaParams())).success)

    def test_5_help_needs_no_master(self):
        status, output = run_node("--help", "__master:=http://localhost:1/")
        self.assertEqual(status, 0, output)
        for text in (ONE, BATCH, "~N_neighbors_aware", "~timeStep", "~neighborDist", "~timeHorizon",
                     "~agent_radius", "~maxSpeed", "~max_neighbors", "~max_agents", "100000"):
            self.assertIn(text, output)

    def test_6_unknown_argument_exits_2(self):
        status, output = run_node("--time-horizon", "4")
        self.assertEqual(status, 2, output)
        self.assertIn("unknown argument '--time-horizon'", output)

    def test_7_bad_parameters_exit_2_naming_the_parameter(self):
        cases = [(["_timeHorizon:=-1"], "~timeHorizon is -1"),
                 (["_timeStep:=0"], "~timeStep is 0"),
                 (["_maxSpeed:=fast"], "~maxSpeed is the string 'fast'"),
                 (["_N_neighbors_aware:=2000"], "~N_neighbors_aware is 2000: above the cap of 1000 neighbours"),
                 (["_max_agents:=0"], "~max_agents is 0"),
                 (["_time_horizon:=4.0"], "~time_horizon is not a parameter of orca3d_server")]
        for k, (args, expected) in enumerate(cases):
            name = f"orca3d_bad_{k}"
            try:
                status, output = run_node(f"__name:={name}", *args)
            finally:
                if rospy.has_param("/" + name):
                    rospy.delete_param("/" + name)
            self.assertEqual(status, 2, output)
            self.assertIn(expected, output)

    def test_8_service_names_can_be_remapped(self):
        remapped = "/elsewhere/compute_velocity"
        process = subprocess.Popen([node_binary(), "__name:=orca3d_remapped", f"{ONE}:={remapped}"],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            rospy.wait_for_service(remapped, timeout=30)
            agent, neighbors = scenarios()["head_on"]
            response = rospy.ServiceProxy(remapped, OrcaComputeVelocity)(
                OrcaComputeVelocityRequest(agent=agent, neighbors=neighbors, params=OrcaParams()))
            self.assertTrue(response.success, response.message)
        finally:
            process.send_signal(signal.SIGINT)
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


if __name__ == "__main__":
    rostest.rosrun("magna_orca_cpp", "orca3d_server_rostest", Orca3dServerTest)

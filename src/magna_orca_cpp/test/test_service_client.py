"""UAV managers' entry point: the C++ service when it is up, the numpy reference when it is not."""
import dataclasses
import subprocess

import numpy as np
import pytest

from magna_orca_cpp import native, reference
from magna_orca_cpp.model import Params
from magna_orca_cpp.scenarios import scenarios
from magna_orca_cpp.validation import OrcaInputError
from tests.support import wait_until

pytestmark = pytest.mark.ros

# Private names, so this test's server cannot meet another test's.
ONE, BATCH, MANY = "/orca_client_test/one", "/orca_client_test/batch", "/orca_client_test/many"


@pytest.fixture
def client(rospy_node):
    from magna_orca_cpp.service_client import OrcaServiceClient

    client = OrcaServiceClient(ONE, BATCH, MANY)
    yield client
    client.close()


def start_server(master):
    return master.spawn(["rosrun", "magna_orca_cpp", "orca3d_server", f"/magna/orca3d/compute_velocity:={ONE}",
                         f"/magna/orca3d/compute_velocities:={BATCH}", f"/magna/orca3d/compute_velocity_many:={MANY}",
                         "__name:=orca_client_test_server"],
                        stdout=subprocess.DEVNULL)


def end(process):
    process.terminate()
    process.wait(10)


def test_the_packed_many_request_is_what_genpy_would_write():
    import io

    from magna_msgs.srv import OrcaComputeVelocityManyRequest

    from magna_orca_cpp.service_client import many_request_bytes, problem_to_msg

    problems = list(scenarios(seed=4, count=30, n_neighbors=(0, 9)))
    problems[4].neighbors = []
    problems[7].params = Params()
    written = io.BytesIO()
    OrcaComputeVelocityManyRequest(problems=[problem_to_msg(p) for p in problems]).serialize(written)
    assert many_request_bytes(problems) == written.getvalue()
    empty = io.BytesIO()
    OrcaComputeVelocityManyRequest(problems=[]).serialize(empty)
    assert many_request_bytes([]) == empty.getvalue()


def test_solver_falls_back_to_the_reference_and_switches_when_the_server_goes(ros_master, client):
    from magna_orca_cpp.service_client import OrcaSolver

    cases = scenarios(seed=8, count=20, n_neighbors=(1, 12))
    absent = OrcaSolver(client)
    assert not absent.using_service
    for s in cases:
        np.testing.assert_allclose(absent.new_velocity(s.agent, s.neighbors, s.params).velocity,
                                   reference.new_velocity(s.agent, s.neighbors, s.params).velocity, atol=1e-12)
    for got, s in zip(absent.new_velocity_many(cases), cases, strict=True):
        assert got.velocity.tobytes() == reference.new_velocity(s.agent, s.neighbors, s.params).velocity.tobytes()

    server = start_server(ros_master)
    try:
        present = OrcaSolver(client, wait=30.0)
        assert present.using_service
        for s in cases:
            answer = present.new_velocity(s.agent, s.neighbors, s.params)
            expected = native.new_velocity(s.agent, s.neighbors, s.params)
            assert answer.feasible == expected.feasible
            np.testing.assert_allclose(answer.velocity, expected.velocity, atol=1e-9)
        batch = client.new_velocities([s.agent for s in cases], Params())
        for got, want in zip(batch, native.new_velocities([s.agent for s in cases], Params()), strict=True):
            np.testing.assert_allclose(got.velocity, want.velocity, atol=1e-9)
        with pytest.raises(OrcaInputError, match="params.time_horizon"):
            client.new_velocity(cases[0].agent, cases[0].neighbors, Params(time_horizon=-1.0))

        # Many problems in one call: each answer is its one-agent call's, bit for bit
        many = present.new_velocity_many(cases)
        assert len(many) == len(cases)
        for got, s in zip(many, cases, strict=True):
            one = client.new_velocity(s.agent, s.neighbors, s.params)
            assert got.velocity.tobytes() == one.velocity.tobytes() and got.feasible == one.feasible
        assert client.new_velocity_many([]) == []
        bad = list(cases[:5])
        bad[3] = dataclasses.replace(bad[3], params=Params(time_horizon=0.0))
        with pytest.raises(OrcaInputError, match=r"^problems\[3\]\.params\.time_horizon \(timeHorizon\) is 0"):
            client.new_velocity_many(bad)
    finally:
        end(server)
    wait_until(lambda: server.poll() is not None, "the server to end")

    for got, s in zip(present.new_velocity_many(cases[:3]), cases, strict=False):
        assert got.velocity.tobytes() == reference.new_velocity(s.agent, s.neighbors, s.params).velocity.tobytes()
    assert not present.using_service, "a vanished server switches the many-call to the reference too"
    present.using_service = True
    s = cases[0]
    answer = present.new_velocity(s.agent, s.neighbors, s.params)
    assert not present.using_service, "a vanished server switches the solver to the reference"
    np.testing.assert_allclose(answer.velocity, reference.new_velocity(s.agent, s.neighbors, s.params).velocity)

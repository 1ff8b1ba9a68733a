"""The PX4-like vehicle's parameter table: PX4's names, bytewise integers, refusals that name the parameter."""
import math
import struct

import pytest

from magna_sim.mavlink_params import (
    MAV_PARAM_TYPE_INT32,
    MAV_PARAM_TYPE_REAL32,
    ParamError,
    ParamTable,
    decode,
    default_params,
    encode,
)


@pytest.fixture
def table():
    return ParamTable(default_params(system_id=2, max_horizontal_speed=10.0, max_vertical_speed=3.0))


def test_px4_defaults_and_the_airframe_limits(table):
    assert table["MIS_TAKEOFF_ALT"] == 2.5 and table["COM_OF_LOSS_T"] == 1.0 and table["COM_DISARM_LAND"] == 2.0
    assert table["MAV_SYS_ID"] == 2 and table["MPC_XY_VEL_MAX"] == 10.0 and table["MPC_Z_VEL_MAX_UP"] == 3.0
    names = [p.name for p in table]
    assert names == sorted(names) and table.find("COM_OF_LOSS_T")[0] == names.index("COM_OF_LOSS_T")
    assert table.find(index=0)[1].name == names[0] and table.find(index=len(table)) is None
    assert table.find("NOPE") is None


@pytest.mark.parametrize("value", [0, 4, -1, 2**31 - 1])
def test_integers_travel_bytewise_as_px4_sends_them(value):
    param = default_params(1, 10.0, 3.0)[0]
    param.value, param.param_type = value, MAV_PARAM_TYPE_INT32
    wire = encode(param)
    assert struct.pack("<f", wire) == struct.pack("<i", value)
    assert decode(wire, MAV_PARAM_TYPE_INT32) == value


def test_set_applies_checks_and_names_what_is_wrong(table):
    assert table.set("MIS_TAKEOFF_ALT", 5.0, MAV_PARAM_TYPE_REAL32)[1].value == 5.0
    assert table["MIS_TAKEOFF_ALT"] == 5.0
    with pytest.raises(ParamError, match="PARAM_SET 'MIS_TAKEOFF_ALT': type 6, but MIS_TAKEOFF_ALT is of type 9"):
        table.set("MIS_TAKEOFF_ALT", 5.0, MAV_PARAM_TYPE_INT32)
    with pytest.raises(ParamError, match=r"PARAM_SET 'MIS_TAKEOFF_ALT': -1.0 is outside \[0.5, 100\]"):
        table.set("MIS_TAKEOFF_ALT", -1.0, MAV_PARAM_TYPE_REAL32)
    with pytest.raises(ParamError, match=r"outside"):
        table.set("COM_OF_LOSS_T", math.nan, MAV_PARAM_TYPE_REAL32)
    with pytest.raises(ParamError, match="PARAM_SET 'NOPE': no such parameter; known: COM_DISARM_LAND"):
        table.set("NOPE", 1.0, MAV_PARAM_TYPE_REAL32)
    assert table.set("MPC_XY_VEL_MAX", 20.0, MAV_PARAM_TYPE_REAL32)[1].value == 10.0  # read-only: unchanged

from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class ShipValues(_message.Message):
    __slots__ = ("ship_id", "state", "tilt_deg", "mass", "fuel_mass", "altitude", "penetration", "peak_penetration", "v_radial", "v_tangential", "normal_force", "friction_force", "throttle", "energy_guard_j", "east", "north", "up", "v_east", "v_north", "v_up", "omega_x", "omega_y", "omega_z", "energy_j")
    SHIP_ID_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    TILT_DEG_FIELD_NUMBER: _ClassVar[int]
    MASS_FIELD_NUMBER: _ClassVar[int]
    FUEL_MASS_FIELD_NUMBER: _ClassVar[int]
    ALTITUDE_FIELD_NUMBER: _ClassVar[int]
    PENETRATION_FIELD_NUMBER: _ClassVar[int]
    PEAK_PENETRATION_FIELD_NUMBER: _ClassVar[int]
    V_RADIAL_FIELD_NUMBER: _ClassVar[int]
    V_TANGENTIAL_FIELD_NUMBER: _ClassVar[int]
    NORMAL_FORCE_FIELD_NUMBER: _ClassVar[int]
    FRICTION_FORCE_FIELD_NUMBER: _ClassVar[int]
    THROTTLE_FIELD_NUMBER: _ClassVar[int]
    ENERGY_GUARD_J_FIELD_NUMBER: _ClassVar[int]
    EAST_FIELD_NUMBER: _ClassVar[int]
    NORTH_FIELD_NUMBER: _ClassVar[int]
    UP_FIELD_NUMBER: _ClassVar[int]
    V_EAST_FIELD_NUMBER: _ClassVar[int]
    V_NORTH_FIELD_NUMBER: _ClassVar[int]
    V_UP_FIELD_NUMBER: _ClassVar[int]
    OMEGA_X_FIELD_NUMBER: _ClassVar[int]
    OMEGA_Y_FIELD_NUMBER: _ClassVar[int]
    OMEGA_Z_FIELD_NUMBER: _ClassVar[int]
    ENERGY_J_FIELD_NUMBER: _ClassVar[int]
    ship_id: str
    state: str
    tilt_deg: float
    mass: float
    fuel_mass: float
    altitude: float
    penetration: float
    peak_penetration: float
    v_radial: float
    v_tangential: float
    normal_force: float
    friction_force: float
    throttle: float
    energy_guard_j: float
    east: float
    north: float
    up: float
    v_east: float
    v_north: float
    v_up: float
    omega_x: float
    omega_y: float
    omega_z: float
    energy_j: float
    def __init__(self, ship_id: _Optional[str] = ..., state: _Optional[str] = ..., tilt_deg: _Optional[float] = ..., mass: _Optional[float] = ..., fuel_mass: _Optional[float] = ..., altitude: _Optional[float] = ..., penetration: _Optional[float] = ..., peak_penetration: _Optional[float] = ..., v_radial: _Optional[float] = ..., v_tangential: _Optional[float] = ..., normal_force: _Optional[float] = ..., friction_force: _Optional[float] = ..., throttle: _Optional[float] = ..., energy_guard_j: _Optional[float] = ..., east: _Optional[float] = ..., north: _Optional[float] = ..., up: _Optional[float] = ..., v_east: _Optional[float] = ..., v_north: _Optional[float] = ..., v_up: _Optional[float] = ..., omega_x: _Optional[float] = ..., omega_y: _Optional[float] = ..., omega_z: _Optional[float] = ..., energy_j: _Optional[float] = ...) -> None: ...

class FleetValues(_message.Message):
    __slots__ = ("tick", "t", "ships")
    TICK_FIELD_NUMBER: _ClassVar[int]
    T_FIELD_NUMBER: _ClassVar[int]
    SHIPS_FIELD_NUMBER: _ClassVar[int]
    tick: int
    t: float
    ships: _containers.RepeatedCompositeFieldContainer[ShipValues]
    def __init__(self, tick: _Optional[int] = ..., t: _Optional[float] = ..., ships: _Optional[_Iterable[_Union[ShipValues, _Mapping]]] = ...) -> None: ...

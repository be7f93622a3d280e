from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class SurfaceState(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    SURFACE_STATE_FLYING: _ClassVar[SurfaceState]
    SURFACE_STATE_CONTACT: _ClassVar[SurfaceState]
    SURFACE_STATE_LANDED: _ClassVar[SurfaceState]
    SURFACE_STATE_TIPPED: _ClassVar[SurfaceState]
    SURFACE_STATE_CRASHED: _ClassVar[SurfaceState]

class HoldMode(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    HOLD_MODE_OFF: _ClassVar[HoldMode]
    HOLD_MODE_KILL_ROTATION: _ClassVar[HoldMode]
    HOLD_MODE_RADIAL: _ClassVar[HoldMode]
SURFACE_STATE_FLYING: SurfaceState
SURFACE_STATE_CONTACT: SurfaceState
SURFACE_STATE_LANDED: SurfaceState
SURFACE_STATE_TIPPED: SurfaceState
SURFACE_STATE_CRASHED: SurfaceState
HOLD_MODE_OFF: HoldMode
HOLD_MODE_KILL_ROTATION: HoldMode
HOLD_MODE_RADIAL: HoldMode

class Vec3(_message.Message):
    __slots__ = ("x", "y", "z")
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_FIELD_NUMBER: _ClassVar[int]
    x: float
    y: float
    z: float
    def __init__(self, x: _Optional[float] = ..., y: _Optional[float] = ..., z: _Optional[float] = ...) -> None: ...

class Quaternion(_message.Message):
    __slots__ = ("w", "x", "y", "z")
    W_FIELD_NUMBER: _ClassVar[int]
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_FIELD_NUMBER: _ClassVar[int]
    w: float
    x: float
    y: float
    z: float
    def __init__(self, w: _Optional[float] = ..., x: _Optional[float] = ..., y: _Optional[float] = ..., z: _Optional[float] = ...) -> None: ...

class ShipState(_message.Message):
    __slots__ = ("ship_id", "player_id", "landed_body_name", "position_m", "velocity_mps", "attitude", "omega_body_radps", "mass_kg", "fuel_kg", "state", "tilt_deg", "surface_contact_state")
    SHIP_ID_FIELD_NUMBER: _ClassVar[int]
    PLAYER_ID_FIELD_NUMBER: _ClassVar[int]
    LANDED_BODY_NAME_FIELD_NUMBER: _ClassVar[int]
    POSITION_M_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_MPS_FIELD_NUMBER: _ClassVar[int]
    ATTITUDE_FIELD_NUMBER: _ClassVar[int]
    OMEGA_BODY_RADPS_FIELD_NUMBER: _ClassVar[int]
    MASS_KG_FIELD_NUMBER: _ClassVar[int]
    FUEL_KG_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    TILT_DEG_FIELD_NUMBER: _ClassVar[int]
    SURFACE_CONTACT_STATE_FIELD_NUMBER: _ClassVar[int]
    ship_id: str
    player_id: str
    landed_body_name: str
    position_m: Vec3
    velocity_mps: Vec3
    attitude: Quaternion
    omega_body_radps: Vec3
    mass_kg: float
    fuel_kg: float
    state: SurfaceState
    tilt_deg: float
    surface_contact_state: str
    def __init__(self, ship_id: _Optional[str] = ..., player_id: _Optional[str] = ..., landed_body_name: _Optional[str] = ..., position_m: _Optional[_Union[Vec3, _Mapping]] = ..., velocity_mps: _Optional[_Union[Vec3, _Mapping]] = ..., attitude: _Optional[_Union[Quaternion, _Mapping]] = ..., omega_body_radps: _Optional[_Union[Vec3, _Mapping]] = ..., mass_kg: _Optional[float] = ..., fuel_kg: _Optional[float] = ..., state: _Optional[_Union[SurfaceState, str]] = ..., tilt_deg: _Optional[float] = ..., surface_contact_state: _Optional[str] = ...) -> None: ...

class ScenarioRecord(_message.Message):
    __slots__ = ("log_format_version", "project_version", "name", "description", "resolved_json", "integrator", "dt_s", "ship_ids", "player_ids", "body", "source", "n_ticks", "keyframe_interval", "start_tick", "open_ended", "keyframe_phase", "shard", "shard_epoch", "shard_taken_us")
    LOG_FORMAT_VERSION_FIELD_NUMBER: _ClassVar[int]
    PROJECT_VERSION_FIELD_NUMBER: _ClassVar[int]
    NAME_FIELD_NUMBER: _ClassVar[int]
    DESCRIPTION_FIELD_NUMBER: _ClassVar[int]
    RESOLVED_JSON_FIELD_NUMBER: _ClassVar[int]
    INTEGRATOR_FIELD_NUMBER: _ClassVar[int]
    DT_S_FIELD_NUMBER: _ClassVar[int]
    SHIP_IDS_FIELD_NUMBER: _ClassVar[int]
    PLAYER_IDS_FIELD_NUMBER: _ClassVar[int]
    BODY_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FIELD_NUMBER: _ClassVar[int]
    N_TICKS_FIELD_NUMBER: _ClassVar[int]
    KEYFRAME_INTERVAL_FIELD_NUMBER: _ClassVar[int]
    START_TICK_FIELD_NUMBER: _ClassVar[int]
    OPEN_ENDED_FIELD_NUMBER: _ClassVar[int]
    KEYFRAME_PHASE_FIELD_NUMBER: _ClassVar[int]
    SHARD_FIELD_NUMBER: _ClassVar[int]
    SHARD_EPOCH_FIELD_NUMBER: _ClassVar[int]
    SHARD_TAKEN_US_FIELD_NUMBER: _ClassVar[int]
    log_format_version: int
    project_version: str
    name: str
    description: str
    resolved_json: str
    integrator: str
    dt_s: float
    ship_ids: _containers.RepeatedScalarFieldContainer[str]
    player_ids: _containers.RepeatedScalarFieldContainer[str]
    body: str
    source: str
    n_ticks: int
    keyframe_interval: int
    start_tick: int
    open_ended: bool
    keyframe_phase: int
    shard: int
    shard_epoch: str
    shard_taken_us: int
    def __init__(self, log_format_version: _Optional[int] = ..., project_version: _Optional[str] = ..., name: _Optional[str] = ..., description: _Optional[str] = ..., resolved_json: _Optional[str] = ..., integrator: _Optional[str] = ..., dt_s: _Optional[float] = ..., ship_ids: _Optional[_Iterable[str]] = ..., player_ids: _Optional[_Iterable[str]] = ..., body: _Optional[str] = ..., source: _Optional[str] = ..., n_ticks: _Optional[int] = ..., keyframe_interval: _Optional[int] = ..., start_tick: _Optional[int] = ..., open_ended: _Optional[bool] = ..., keyframe_phase: _Optional[int] = ..., shard: _Optional[int] = ..., shard_epoch: _Optional[str] = ..., shard_taken_us: _Optional[int] = ...) -> None: ...

class TickBatch(_message.Message):
    __slots__ = ("tick", "t_s", "ship_count", "surface_state", "pos_m", "vel_mps", "quat", "omega_body_radps", "mass_kg", "fuel_kg", "absorbing", "sliding", "settle_ticks", "pivot_rate_radps", "pin_pos_bf_m", "pin_quat_bf", "pin_pivot_bf_m", "settle_for_s", "settle_margin", "hold_force_n", "altitude_m", "penetration_m", "cos_tilt", "v_radial_mps", "v_tangential_mps", "normal_force_n", "friction_force_n", "throttle", "rcs_torque_body_nm", "peak_penetration_m", "energy_guard_j", "input_throttle", "input_rcs", "input_hold", "ship_key")
    TICK_FIELD_NUMBER: _ClassVar[int]
    T_S_FIELD_NUMBER: _ClassVar[int]
    SHIP_COUNT_FIELD_NUMBER: _ClassVar[int]
    SURFACE_STATE_FIELD_NUMBER: _ClassVar[int]
    POS_M_FIELD_NUMBER: _ClassVar[int]
    VEL_MPS_FIELD_NUMBER: _ClassVar[int]
    QUAT_FIELD_NUMBER: _ClassVar[int]
    OMEGA_BODY_RADPS_FIELD_NUMBER: _ClassVar[int]
    MASS_KG_FIELD_NUMBER: _ClassVar[int]
    FUEL_KG_FIELD_NUMBER: _ClassVar[int]
    ABSORBING_FIELD_NUMBER: _ClassVar[int]
    SLIDING_FIELD_NUMBER: _ClassVar[int]
    SETTLE_TICKS_FIELD_NUMBER: _ClassVar[int]
    PIVOT_RATE_RADPS_FIELD_NUMBER: _ClassVar[int]
    PIN_POS_BF_M_FIELD_NUMBER: _ClassVar[int]
    PIN_QUAT_BF_FIELD_NUMBER: _ClassVar[int]
    PIN_PIVOT_BF_M_FIELD_NUMBER: _ClassVar[int]
    SETTLE_FOR_S_FIELD_NUMBER: _ClassVar[int]
    SETTLE_MARGIN_FIELD_NUMBER: _ClassVar[int]
    HOLD_FORCE_N_FIELD_NUMBER: _ClassVar[int]
    ALTITUDE_M_FIELD_NUMBER: _ClassVar[int]
    PENETRATION_M_FIELD_NUMBER: _ClassVar[int]
    COS_TILT_FIELD_NUMBER: _ClassVar[int]
    V_RADIAL_MPS_FIELD_NUMBER: _ClassVar[int]
    V_TANGENTIAL_MPS_FIELD_NUMBER: _ClassVar[int]
    NORMAL_FORCE_N_FIELD_NUMBER: _ClassVar[int]
    FRICTION_FORCE_N_FIELD_NUMBER: _ClassVar[int]
    THROTTLE_FIELD_NUMBER: _ClassVar[int]
    RCS_TORQUE_BODY_NM_FIELD_NUMBER: _ClassVar[int]
    PEAK_PENETRATION_M_FIELD_NUMBER: _ClassVar[int]
    ENERGY_GUARD_J_FIELD_NUMBER: _ClassVar[int]
    INPUT_THROTTLE_FIELD_NUMBER: _ClassVar[int]
    INPUT_RCS_FIELD_NUMBER: _ClassVar[int]
    INPUT_HOLD_FIELD_NUMBER: _ClassVar[int]
    SHIP_KEY_FIELD_NUMBER: _ClassVar[int]
    tick: int
    t_s: float
    ship_count: int
    surface_state: _containers.RepeatedScalarFieldContainer[SurfaceState]
    pos_m: _containers.RepeatedScalarFieldContainer[float]
    vel_mps: _containers.RepeatedScalarFieldContainer[float]
    quat: _containers.RepeatedScalarFieldContainer[float]
    omega_body_radps: _containers.RepeatedScalarFieldContainer[float]
    mass_kg: _containers.RepeatedScalarFieldContainer[float]
    fuel_kg: _containers.RepeatedScalarFieldContainer[float]
    absorbing: _containers.RepeatedScalarFieldContainer[bool]
    sliding: _containers.RepeatedScalarFieldContainer[bool]
    settle_ticks: _containers.RepeatedScalarFieldContainer[int]
    pivot_rate_radps: _containers.RepeatedScalarFieldContainer[float]
    pin_pos_bf_m: _containers.RepeatedScalarFieldContainer[float]
    pin_quat_bf: _containers.RepeatedScalarFieldContainer[float]
    pin_pivot_bf_m: _containers.RepeatedScalarFieldContainer[float]
    settle_for_s: _containers.RepeatedScalarFieldContainer[float]
    settle_margin: _containers.RepeatedScalarFieldContainer[float]
    hold_force_n: _containers.RepeatedScalarFieldContainer[float]
    altitude_m: _containers.RepeatedScalarFieldContainer[float]
    penetration_m: _containers.RepeatedScalarFieldContainer[float]
    cos_tilt: _containers.RepeatedScalarFieldContainer[float]
    v_radial_mps: _containers.RepeatedScalarFieldContainer[float]
    v_tangential_mps: _containers.RepeatedScalarFieldContainer[float]
    normal_force_n: _containers.RepeatedScalarFieldContainer[float]
    friction_force_n: _containers.RepeatedScalarFieldContainer[float]
    throttle: _containers.RepeatedScalarFieldContainer[float]
    rcs_torque_body_nm: _containers.RepeatedScalarFieldContainer[float]
    peak_penetration_m: _containers.RepeatedScalarFieldContainer[float]
    energy_guard_j: _containers.RepeatedScalarFieldContainer[float]
    input_throttle: _containers.RepeatedScalarFieldContainer[float]
    input_rcs: _containers.RepeatedScalarFieldContainer[float]
    input_hold: _containers.RepeatedScalarFieldContainer[HoldMode]
    ship_key: _containers.RepeatedScalarFieldContainer[int]
    def __init__(self, tick: _Optional[int] = ..., t_s: _Optional[float] = ..., ship_count: _Optional[int] = ..., surface_state: _Optional[_Iterable[_Union[SurfaceState, str]]] = ..., pos_m: _Optional[_Iterable[float]] = ..., vel_mps: _Optional[_Iterable[float]] = ..., quat: _Optional[_Iterable[float]] = ..., omega_body_radps: _Optional[_Iterable[float]] = ..., mass_kg: _Optional[_Iterable[float]] = ..., fuel_kg: _Optional[_Iterable[float]] = ..., absorbing: _Optional[_Iterable[bool]] = ..., sliding: _Optional[_Iterable[bool]] = ..., settle_ticks: _Optional[_Iterable[int]] = ..., pivot_rate_radps: _Optional[_Iterable[float]] = ..., pin_pos_bf_m: _Optional[_Iterable[float]] = ..., pin_quat_bf: _Optional[_Iterable[float]] = ..., pin_pivot_bf_m: _Optional[_Iterable[float]] = ..., settle_for_s: _Optional[_Iterable[float]] = ..., settle_margin: _Optional[_Iterable[float]] = ..., hold_force_n: _Optional[_Iterable[float]] = ..., altitude_m: _Optional[_Iterable[float]] = ..., penetration_m: _Optional[_Iterable[float]] = ..., cos_tilt: _Optional[_Iterable[float]] = ..., v_radial_mps: _Optional[_Iterable[float]] = ..., v_tangential_mps: _Optional[_Iterable[float]] = ..., normal_force_n: _Optional[_Iterable[float]] = ..., friction_force_n: _Optional[_Iterable[float]] = ..., throttle: _Optional[_Iterable[float]] = ..., rcs_torque_body_nm: _Optional[_Iterable[float]] = ..., peak_penetration_m: _Optional[_Iterable[float]] = ..., energy_guard_j: _Optional[_Iterable[float]] = ..., input_throttle: _Optional[_Iterable[float]] = ..., input_rcs: _Optional[_Iterable[float]] = ..., input_hold: _Optional[_Iterable[_Union[HoldMode, str]]] = ..., ship_key: _Optional[_Iterable[int]] = ...) -> None: ...

class ShipJoined(_message.Message):
    __slots__ = ("ship_key", "ship_id", "player_id", "spec_json")
    SHIP_KEY_FIELD_NUMBER: _ClassVar[int]
    SHIP_ID_FIELD_NUMBER: _ClassVar[int]
    PLAYER_ID_FIELD_NUMBER: _ClassVar[int]
    SPEC_JSON_FIELD_NUMBER: _ClassVar[int]
    ship_key: int
    ship_id: str
    player_id: str
    spec_json: str
    def __init__(self, ship_key: _Optional[int] = ..., ship_id: _Optional[str] = ..., player_id: _Optional[str] = ..., spec_json: _Optional[str] = ...) -> None: ...

class FleetChange(_message.Message):
    __slots__ = ("tick", "joined", "left_ship_key", "left_ship_id")
    TICK_FIELD_NUMBER: _ClassVar[int]
    JOINED_FIELD_NUMBER: _ClassVar[int]
    LEFT_SHIP_KEY_FIELD_NUMBER: _ClassVar[int]
    LEFT_SHIP_ID_FIELD_NUMBER: _ClassVar[int]
    tick: int
    joined: _containers.RepeatedCompositeFieldContainer[ShipJoined]
    left_ship_key: _containers.RepeatedScalarFieldContainer[int]
    left_ship_id: _containers.RepeatedScalarFieldContainer[str]
    def __init__(self, tick: _Optional[int] = ..., joined: _Optional[_Iterable[_Union[ShipJoined, _Mapping]]] = ..., left_ship_key: _Optional[_Iterable[int]] = ..., left_ship_id: _Optional[_Iterable[str]] = ...) -> None: ...

class Command(_message.Message):
    __slots__ = ("tick", "ship_id", "throttle", "rcs", "hold")
    TICK_FIELD_NUMBER: _ClassVar[int]
    SHIP_ID_FIELD_NUMBER: _ClassVar[int]
    THROTTLE_FIELD_NUMBER: _ClassVar[int]
    RCS_FIELD_NUMBER: _ClassVar[int]
    HOLD_FIELD_NUMBER: _ClassVar[int]
    tick: int
    ship_id: str
    throttle: float
    rcs: _containers.RepeatedScalarFieldContainer[float]
    hold: HoldMode
    def __init__(self, tick: _Optional[int] = ..., ship_id: _Optional[str] = ..., throttle: _Optional[float] = ..., rcs: _Optional[_Iterable[float]] = ..., hold: _Optional[_Union[HoldMode, str]] = ...) -> None: ...

class CommandBatch(_message.Message):
    __slots__ = ("tick", "commands")
    TICK_FIELD_NUMBER: _ClassVar[int]
    COMMANDS_FIELD_NUMBER: _ClassVar[int]
    tick: int
    commands: _containers.RepeatedCompositeFieldContainer[Command]
    def __init__(self, tick: _Optional[int] = ..., commands: _Optional[_Iterable[_Union[Command, _Mapping]]] = ...) -> None: ...

class TransitionEvent(_message.Message):
    __slots__ = ("event", "tick", "t_s", "ship_id", "player_id", "body", "from_state", "to_state", "ship", "v_radial_mps", "t_event_s")
    EVENT_FIELD_NUMBER: _ClassVar[int]
    TICK_FIELD_NUMBER: _ClassVar[int]
    T_S_FIELD_NUMBER: _ClassVar[int]
    SHIP_ID_FIELD_NUMBER: _ClassVar[int]
    PLAYER_ID_FIELD_NUMBER: _ClassVar[int]
    BODY_FIELD_NUMBER: _ClassVar[int]
    FROM_STATE_FIELD_NUMBER: _ClassVar[int]
    TO_STATE_FIELD_NUMBER: _ClassVar[int]
    SHIP_FIELD_NUMBER: _ClassVar[int]
    V_RADIAL_MPS_FIELD_NUMBER: _ClassVar[int]
    T_EVENT_S_FIELD_NUMBER: _ClassVar[int]
    event: str
    tick: int
    t_s: float
    ship_id: str
    player_id: str
    body: str
    from_state: SurfaceState
    to_state: SurfaceState
    ship: ShipState
    v_radial_mps: float
    t_event_s: float
    def __init__(self, event: _Optional[str] = ..., tick: _Optional[int] = ..., t_s: _Optional[float] = ..., ship_id: _Optional[str] = ..., player_id: _Optional[str] = ..., body: _Optional[str] = ..., from_state: _Optional[_Union[SurfaceState, str]] = ..., to_state: _Optional[_Union[SurfaceState, str]] = ..., ship: _Optional[_Union[ShipState, _Mapping]] = ..., v_radial_mps: _Optional[float] = ..., t_event_s: _Optional[float] = ...) -> None: ...

class LogSummary(_message.Message):
    __slots__ = ("last_tick", "complete", "reason", "event_count", "superseded_after_tick")
    LAST_TICK_FIELD_NUMBER: _ClassVar[int]
    COMPLETE_FIELD_NUMBER: _ClassVar[int]
    REASON_FIELD_NUMBER: _ClassVar[int]
    EVENT_COUNT_FIELD_NUMBER: _ClassVar[int]
    SUPERSEDED_AFTER_TICK_FIELD_NUMBER: _ClassVar[int]
    last_tick: int
    complete: bool
    reason: str
    event_count: int
    superseded_after_tick: int
    def __init__(self, last_tick: _Optional[int] = ..., complete: _Optional[bool] = ..., reason: _Optional[str] = ..., event_count: _Optional[int] = ..., superseded_after_tick: _Optional[int] = ...) -> None: ...

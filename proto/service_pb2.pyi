from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable
from typing import ClassVar as _ClassVar, Optional as _Optional

DESCRIPTOR: _descriptor.FileDescriptor

class ShardCheckpoint(_message.Message):
    __slots__ = ("format", "shard", "shards", "tick", "scene_json", "ship_ids", "player_ids", "ship_rows", "state_rows", "input_rows", "dtypes", "autoland", "published")
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    SHARD_FIELD_NUMBER: _ClassVar[int]
    SHARDS_FIELD_NUMBER: _ClassVar[int]
    TICK_FIELD_NUMBER: _ClassVar[int]
    SCENE_JSON_FIELD_NUMBER: _ClassVar[int]
    SHIP_IDS_FIELD_NUMBER: _ClassVar[int]
    PLAYER_IDS_FIELD_NUMBER: _ClassVar[int]
    SHIP_ROWS_FIELD_NUMBER: _ClassVar[int]
    STATE_ROWS_FIELD_NUMBER: _ClassVar[int]
    INPUT_ROWS_FIELD_NUMBER: _ClassVar[int]
    DTYPES_FIELD_NUMBER: _ClassVar[int]
    AUTOLAND_FIELD_NUMBER: _ClassVar[int]
    PUBLISHED_FIELD_NUMBER: _ClassVar[int]
    format: int
    shard: int
    shards: int
    tick: int
    scene_json: str
    ship_ids: _containers.RepeatedScalarFieldContainer[str]
    player_ids: _containers.RepeatedScalarFieldContainer[str]
    ship_rows: bytes
    state_rows: bytes
    input_rows: bytes
    dtypes: str
    autoland: _containers.RepeatedScalarFieldContainer[str]
    published: int
    def __init__(self, format: _Optional[int] = ..., shard: _Optional[int] = ..., shards: _Optional[int] = ..., tick: _Optional[int] = ..., scene_json: _Optional[str] = ..., ship_ids: _Optional[_Iterable[str]] = ..., player_ids: _Optional[_Iterable[str]] = ..., ship_rows: _Optional[bytes] = ..., state_rows: _Optional[bytes] = ..., input_rows: _Optional[bytes] = ..., dtypes: _Optional[str] = ..., autoland: _Optional[_Iterable[str]] = ..., published: _Optional[int] = ...) -> None: ...

class Telemetry(_message.Message):
    __slots__ = ("tick", "t_s", "shard", "ship_ids", "state", "pos_m", "vel_mps", "altitude_m", "cos_tilt", "fuel_kg")
    TICK_FIELD_NUMBER: _ClassVar[int]
    T_S_FIELD_NUMBER: _ClassVar[int]
    SHARD_FIELD_NUMBER: _ClassVar[int]
    SHIP_IDS_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    POS_M_FIELD_NUMBER: _ClassVar[int]
    VEL_MPS_FIELD_NUMBER: _ClassVar[int]
    ALTITUDE_M_FIELD_NUMBER: _ClassVar[int]
    COS_TILT_FIELD_NUMBER: _ClassVar[int]
    FUEL_KG_FIELD_NUMBER: _ClassVar[int]
    tick: int
    t_s: float
    shard: int
    ship_ids: _containers.RepeatedScalarFieldContainer[str]
    state: _containers.RepeatedScalarFieldContainer[int]
    pos_m: _containers.RepeatedScalarFieldContainer[float]
    vel_mps: _containers.RepeatedScalarFieldContainer[float]
    altitude_m: _containers.RepeatedScalarFieldContainer[float]
    cos_tilt: _containers.RepeatedScalarFieldContainer[float]
    fuel_kg: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, tick: _Optional[int] = ..., t_s: _Optional[float] = ..., shard: _Optional[int] = ..., ship_ids: _Optional[_Iterable[str]] = ..., state: _Optional[_Iterable[int]] = ..., pos_m: _Optional[_Iterable[float]] = ..., vel_mps: _Optional[_Iterable[float]] = ..., altitude_m: _Optional[_Iterable[float]] = ..., cos_tilt: _Optional[_Iterable[float]] = ..., fuel_kg: _Optional[_Iterable[float]] = ...) -> None: ...

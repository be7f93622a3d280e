"""Reading a Touchdown log (the format: logs.header): its header checked before anything is run
on it, the tick records one at a time (TickData) or as columns a block at a time
(logs.decode), the fleet's joins and leaves, the commands, the events and the summary. CRCs are
checked, sizes bounded (logs.safe_read); any damage raises LogError.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import struct
from pathlib import Path
from typing import Iterator

import numpy as np

from touchdown.logs import LogError
from touchdown.logs.decode import BlockDecoder, TickBlock, varint, decode_tick
from touchdown.logs.header import (LOG_FORMAT_VERSION, TOPIC_COMMANDS, TOPIC_EVENTS, TOPIC_FLEET,
                         TOPIC_SCENARIO, TOPIC_SUMMARY, TOPIC_TICKS, WIDTH, CHUNK_BYTES_MAX,
                         ShipTable, keyframe_due, tick_bytes_bound)
from touchdown.logs.safe_read import (ChunkBuffers, GrowingBound, ReadLimits, ReadStatus,
                                      chunk_at, chunk_checked_at, iter_messages)
from touchdown.logs.structure import Structure
from touchdown.logs.structure import check as check_structure
from touchdown.logs.structure import data_crc_matches
from touchdown.proto import touchdown_pb2 as pb
from touchdown.sim import __version__ as PROJECT_VERSION
from touchdown.sim import fields
from touchdown.sim.state import Inputs, Outputs, State
from touchdown.sim.timeline import Command, CommandError, Retire, Spawn, Timeline

#: how far a log may start (ticks): past any run a scenario may ask for, within a double's integers
MAX_START_TICK = 1 << 53
#: the tick, s: what a scenario may set (sim.scenario), and so what a log may hold
MIN_DT_S, MAX_DT_S = 1e-4, 1.0
MAX_SHIPS = 10_000_000
MAX_SCENARIO_CHARS = 64 << 20
#: the most bytes a scenario record may hold: its scenario (resolved_json: every ship's table,
#: each naming its ship and player), its ship_ids and player_ids (each id a few bytes more than
#: in the JSON, which holds it too), and its short fields. What a log's header read holds (and
#: inflates, with safe_read.HEADER_PREAMBLE_BYTES before it) of its chunk, whatever the chunk
#: declares: the chunk's own bound comes from the header (LogReader._check_header_chunk)
MAX_SCENARIO_RECORD_BYTES = 3 * MAX_SCENARIO_CHARS + (1 << 20)
#: a chunk's records beyond what its writer filled before the record that closed it: the
#: schemas and channels a log's first chunk opens with (8.7-17 kB), with margin
CHUNK_SLACK_BYTES = 1 << 18


def _ends_with_magic(s: Structure) -> bool:
    """The file ends with MCAP's magic (finished; a cut file has none: read as a cut)."""
    return not any(p.part == "footer" and "ends without a footer" in p.what for p in s.problems)


class TickData:
    """One TickBatch as read from a log: the raw bytes, decoded only when a field is asked for
    (a verification that finds the bytes identical never decodes them)."""

    def __init__(self, raw: bytes, tick_from_time: int, where: str = "", ships: int = 0,
                 log_format: int = LOG_FORMAT_VERSION, table_size: int = 0):
        self.raw = raw
        self.tick_from_time = tick_from_time
        self._where = where
        self._ships = ships if log_format < 3 else 0  # format 3: the fleet changes
        self._format = log_format
        self._table_size = table_size
        self._decoded: tuple[int, float, int, dict[str, np.ndarray]] | None = None

    def _decode(self) -> tuple[int, float, int, dict[str, np.ndarray]]:
        if self._decoded is None:
            try:
                decoded = decode_tick(self.raw)
            except LogError as exc:
                raise LogError(f"{self._where}: tick {self.tick_from_time}: {exc}") from None
            self._check(*decoded)
            self._decoded = decoded
        return self._decoded

    def _check(self, tick: int, t_s: float, count: int, arrays: dict[str, np.ndarray]) -> None:
        """Every field a tick must hold, each with exactly ship_count x width numbers, the ship
        count the scenario's, the tick its log time's."""
        where = f"{self._where}: tick {self.tick_from_time}"
        if tick != self.tick_from_time:
            raise LogError(f"{where}: the record says tick {tick}")
        if self._ships and count != self._ships:
            raise LogError(f"{where}: {count} ships where the scenario has {self._ships}")
        for name in fields.EVERY_TICK_BY_FORMAT[self._format]:
            if name not in arrays and count:
                raise LogError(f"{where}: field {name} is missing")
        keyframe = [name in arrays for name in fields.KEYFRAME_BY_FORMAT[self._format]]
        if any(keyframe) and not all(keyframe):
            raise LogError(f"{where}: a keyframe with some of its fields missing")
        for name, a in arrays.items():
            width = 1 if (name == "sliding" and self._format < 2) else WIDTH.get(name, 1)
            if a.size != count * width:
                raise LogError(f"{where}: field {name} holds {a.size} numbers for {count} ships")
        if count and (arrays["surface_state"] > 4).any():
            raise LogError(f"{where}: a surface state out of range")
        keys = arrays.get("ship_key")
        if keys is not None and keys.size and (
                keys.min() < 0 or keys.max() >= self._table_size
                or np.unique(keys).size != keys.size):
            raise LogError(f"{where}: ship keys outside the log's {self._table_size} ships, or "
                           f"a ship twice")

    @property
    def tick(self) -> int:
        return self._decode()[0]

    @property
    def t_s(self) -> float:
        return self._decode()[1]

    @property
    def ship_count(self) -> int:
        return self._decode()[2]

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        return self._decode()[3]

    def vec(self, name: str, width: int) -> np.ndarray:
        return self.arrays[name].reshape(self.ship_count, width)

    @property
    def keys(self) -> np.ndarray:
        """The ships of this tick by key (format 3); before it, the header's ships in order."""
        keys = self.arrays.get("ship_key")
        if keys is None:
            return np.arange(self.ship_count, dtype=np.int64)
        return keys

    @property
    def is_keyframe(self) -> bool:
        return all(name in self.arrays for name in fields.KEYFRAME_BY_FORMAT[self._format]) \
            or self.ship_count == 0

    def state(self) -> State:
        """The full state recorded at this tick (a keyframe)."""
        a = self.arrays
        if not self.is_keyframe:
            raise LogError(f"tick {self.tick} is not a keyframe")
        if self.ship_count == 0:
            return State.zeros(0, tick=self.tick)
        try:
            # a field its format does not have (settle_for_s before format 4) starts at zero
            values = {f.name: self.vec(f.in_log, f.per_ship) if f.per_ship > 1 else a[f.in_log]
                      for f in fields.of_record("state")
                      if f.name != "sliding" and (f.in_log in a or f.in_log in
                                                  fields.EVERY_TICK_BY_FORMAT[self._format]
                                                  + fields.KEYFRAME_BY_FORMAT[self._format])}
            values["absorbing"] = values["absorbing"] != 0
            return State.of(self.ship_count, tick=self.tick, sliding=self._sliding(), **values)
        except (KeyError, ValueError) as exc:
            raise LogError(f"tick {self.tick}: incomplete state record ({exc})") from None

    def _sliding(self) -> np.ndarray:
        a = self.arrays["sliding"].astype(bool)
        if a.size == self.ship_count:  # a format-1 log: one regime per ship
            return np.repeat(a[:, None], 4, axis=1)
        return a.reshape(self.ship_count, 4)

    def outputs(self) -> Outputs:
        """What this tick reported (on every tick)."""
        if self.ship_count == 0:
            return Outputs.zeros(0)
        return Outputs.of(self.ship_count, **{
            f.name: self.vec(f.in_log, f.per_ship) if f.per_ship > 1 else self.arrays[f.in_log]
            for f in fields.of_record("outputs")})

    def inputs(self) -> Inputs:
        """The commands applied during the step into this tick."""
        if self.ship_count == 0:
            return Inputs.zeros(0)
        return Inputs.of(self.ship_count, **{
            f.name: self.vec(f.in_log, f.per_ship) if f.per_ship > 1 else self.arrays[f.in_log]
            for f in fields.of_record("inputs")})


class LogReader:
    """Read a Touchdown log. CRCs are checked; any damage raises :class:`LogError`."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        try:
            self._file = open(self.path, "rb")
        except OSError as exc:
            raise LogError(f"{self.path}: cannot open: {exc.strerror}") from None
        self.scenario: pb.ScenarioRecord | None = None
        self.summary: pb.LogSummary | None = None
        self.status = ReadStatus()
        # the file's MCAP structure (no decompression): a finished file whose summary or footer
        # is damaged but whose data section is whole is read by walking that section
        self.structure = check_structure(self._file)
        st = self.structure
        self._walk = _ends_with_magic(st) and not st.summary_ok and st.data_end >= 0
        self._largest_record = 0
        self._known_chunks: dict = {}  # GrowingBound.known: shared by this log's reads
        # the header, read from its chunk as a stream that stops after it: the fleet it names
        # bounds the chunk (which may hold a large fleet's first tick too), so the chunk is not
        # inflated before it is known; the chunk is read in full (its size and CRC checked) by
        # _check_header_chunk, at once if that bound is known now, else once the fleet is
        for _topic, _t, data in iter_messages(self._file, str(self.path), {TOPIC_SCENARIO},
                                              None, None, self.status, walk=self._walk,
                                              header=MAX_SCENARIO_RECORD_BYTES):
            self._largest_record = len(data)
            try:
                self.scenario = pb.ScenarioRecord.FromString(data)
            except Exception as exc:
                raise LogError(f"{self.path}: damaged scenario record ({exc})") from None
        self._header_chunk, self.status.unchecked = self.status.unchecked, None
        if self.scenario is None:
            why = f"; damaged before it: {self.status.damage}" if self.status.damage else ""
            raise LogError(f"{self.path}: not a Touchdown log (no {TOPIC_SCENARIO} record{why})")
        self._check_record()
        self._check_header_chunk()

    def _check_header_chunk(self, limits: ReadLimits | None = None, ids=None) -> None:
        """The chunk the header was read from (if it was not read to its end), read in full:
        its size and CRC checked, within ``limits`` (those of the log's ticks, of the fleet of
        ``ids``: its ship ids), or by default within what a chunk of the header's ships can
        hold (_limits_for): from format 3 ships may join within the chunk (its last message may
        be a tick of more ships, or their joining), so a chunk over that bound waits for the
        fleet's (_tick_limits and ship_table call this). From format 3 a chunk over the fleet's
        bound is read as every read after the fleet's reads it (_grow_for): its last record may
        be a tick's commands, which the fleet does not bound (a writer that does not end its
        first chunk after the first tick, `touchdown recover`'s, puts the ticks after it and
        their commands there too), passed over; anything else past what a writer fills is
        refused."""
        if self._header_chunk is None:
            return
        offset, declared = self._header_chunk
        if limits is None:
            limits = self._limits_for(len(self.scenario.ship_ids))
            if declared > limits.max_chunk_bytes and self.log_format >= 3:
                return
        if declared > limits.max_chunk_bytes and self.log_format >= 3:
            ids = ids if ids is not None else self.ship_table().ids
            chunk_checked_at(self._file, offset, str(self.path), self._grow_for(limits, ids),
                             {})
        else:
            chunk_at(self._file, offset, str(self.path), limits)
        self._header_chunk = None

    def _check_record(self) -> None:
        """The scenario record's own numbers, before anything is run on them (the resolved
        scenario itself is checked by scenario_of, by the same rules as a scenario file)."""
        sr, where = self.scenario, f"{self.path}: the scenario record"
        if not 1 <= sr.log_format_version <= LOG_FORMAT_VERSION:
            raise LogError(f"{where}: log format {sr.log_format_version}; this touchdown "
                           f"({PROJECT_VERSION}) reads formats 1 to {LOG_FORMAT_VERSION}")
        if not (math.isfinite(sr.dt_s) and MIN_DT_S <= sr.dt_s <= MAX_DT_S):
            raise LogError(f"{where}: dt_s {sr.dt_s!r} is out of range ({MIN_DT_S:g}..{MAX_DT_S:g} s)")
        least = 1 if sr.log_format_version < 3 else 0  # format 3: ships may all join later
        if not least <= len(sr.ship_ids) <= MAX_SHIPS or len(sr.player_ids) != len(sr.ship_ids):
            raise LogError(f"{where}: {len(sr.ship_ids)} ships, {len(sr.player_ids)} players")
        if sr.keyframe_interval > max(1, sr.n_ticks) and not sr.open_ended:
            raise LogError(f"{where}: keyframe_interval {sr.keyframe_interval} exceeds its "
                           f"{sr.n_ticks} ticks")
        if sr.keyframe_phase and sr.log_format_version < 5:
            raise LogError(f"{where}: keyframe_phase in a log of format {sr.log_format_version} "
                           f"(it is of format 5)")
        if sr.keyframe_phase >= max(1, sr.keyframe_interval):
            raise LogError(f"{where}: keyframe_phase {sr.keyframe_phase} is not less than its "
                           f"keyframe_interval {max(1, sr.keyframe_interval)}")
        if (sr.start_tick or sr.open_ended) and sr.log_format_version < 3:
            raise LogError(f"{where}: start_tick or open_ended in a log of format "
                           f"{sr.log_format_version} (they are of format 3)")
        if sr.start_tick >= MAX_START_TICK or (sr.start_tick > sr.n_ticks and not sr.open_ended):
            raise LogError(f"{where}: start_tick {sr.start_tick} is past its run's "
                           f"{'limit' if sr.open_ended else f'last tick {sr.n_ticks}'}")
        if len(sr.resolved_json) > MAX_SCENARIO_CHARS:
            raise LogError(f"{where}: its scenario is {len(sr.resolved_json):,} characters "
                           f"(limit {MAX_SCENARIO_CHARS:,})")

    def _header_chunk_checked(self) -> None:
        """A read of the log's records after its header: the header's chunk, if its check
        waits for the fleet (a log of format 3 or later whose first chunk is over what the
        header's ships fill), is checked first."""
        if self._header_chunk is not None:
            self._tick_limits()

    def structure_note(self) -> str:
        """One line if the file's MCAP structure (its records' fields, message indexes, chunk
        times, summary, footer, the data section's CRC if checked) is damaged while its content
        is readable (logs.structure, and what the reads found), else "". A cut file (no footer)
        is not said to be damaged here: its readers say what they recovered."""
        st = self.structure
        for offset, what in self.status.notes:  # found while reading the chunks
            if not any(p.part == "chunk" and p.where == offset for p in st.problems):
                st.add("chunk", offset, what)
        if not _ends_with_magic(st):
            return Structure(problems=[p for p in st.problems if p.part == "chunk"]).line()
        return st.line()

    def check_data_crc(self) -> bool | None:
        """The data section's bytes against the CRC its Data End record holds (one more read
        of the file); a mismatch is a problem of the structure (structure_note says it).
        Returns whether it matched (None: no CRC, as in a log written before issue 37)."""
        ok = data_crc_matches(self._file, self.structure)
        if ok is False:
            self.structure.add("data end", self.structure.data_end,
                               "the data section's CRC does not match its bytes: a byte before "
                               "it changed, in a record no other CRC covers (its header, its "
                               "metadata, a chunk's fields or a message index)")
        return ok

    def _iter(self, topics: set[str]) -> Iterator[tuple[str, bytes]]:
        for topic, _t, data in self.messages(topics):
            yield topic, data

    def _fleet_bound(self) -> GrowingBound:
        """How a read after the fleet's bounds its chunks: by the whole fleet (_tick_limits),
        save one ending in a tick's commands, which the fleet does not bound (any number a ship
        a tick: World.commands, a scenario's inputs). A chunk over that bound is read as a
        stream (safe_read.GrowingBound): every record but its last within what a writer fills
        before it closes a chunk, and its last a command batch (kept if the read wants it,
        checked field by field as it arrives, else passed over, not held) or else the chunk is
        refused, before it is inflated past a piece of that record. The header's chunk, if its
        check waits for the fleet, is checked first."""
        limits = self._tick_limits()
        return self._grow_for(limits, self.ship_table().ids if self.log_format >= 3
                              else self.scenario.ship_ids)

    def _grow_for(self, limits: ReadLimits, ids) -> GrowingBound:
        """_fleet_bound for the fleet of ``ids`` (the ship ids), whose chunks ``limits`` bound."""
        ships = len(ids)
        where = str(self.path)
        if getattr(self, "_longest_id", (-1,))[0] != len(ids):  # (once per fleet)
            self._longest_id = (len(ids), max((len(i.encode()) for i in ids), default=0))
        command_bytes = COMMAND_BYTES_BUT_ID + self._longest_id[1]

        def refuse(declared: int) -> LogError:
            return LogError(f"{where}: a chunk claims {declared:,} bytes uncompressed (limit "
                            f"{limits.max_chunk_bytes:,}, {limits.chunk_bound}) and does not "
                            f"end in a tick's commands; refusing it")
        return GrowingBound(
            known=self._known_chunks,
            bound=lambda: limits.max_chunk_bytes, prefix=CHUNK_BYTES_MAX + CHUNK_SLACK_BYTES,
            held=max(tick_bytes_bound(ships), self._largest_record),
            check=lambda topic: (_FieldCheck(f"{where}: damaged command record",
                                             _FieldCheck.COMMAND_BATCH, {2: command_bytes})
                                 if topic == TOPIC_COMMANDS else None),
            passed=frozenset({TOPIC_COMMANDS}), refuse=refuse)

    def messages(self, topics: set[str]) -> Iterator[tuple[str, int, bytes]]:
        """(topic, log time ns, bytes) of the messages on ``topics``, in log order, read as
        every reader of this log reads them (through its index, or by walking its data section
        when its summary or footer is damaged), each chunk within the fleet's bound
        (_fleet_bound)."""
        grow = self._fleet_bound()
        yield from iter_messages(self._file, str(self.path), topics, None, None, self.status,
                                 walk=self._walk, grow=grow)

    def raw(self, topic: str, start_ns: int | None = None, end_ns: int | None = None
            ) -> Iterator[tuple[int, bytes]]:
        """(log time ns, message bytes) of one topic's messages, in log order (each chunk
        within the fleet's bound: _fleet_bound)."""
        grow = self._fleet_bound()
        for _topic, t_ns, data in iter_messages(self._file, str(self.path), {topic}, start_ns,
                                                end_ns, self.status, walk=self._walk,
                                                grow=grow):
            yield t_ns, data

    @property
    def keyframe_interval(self) -> int:
        return max(1, int(self.scenario.keyframe_interval))

    @property
    def keyframe_phase(self) -> int:
        """The keyframes after the first fall on ticks = phase (mod the interval); 0 before
        format 5."""
        return int(self.scenario.keyframe_phase)

    @property
    def start_tick(self) -> int:
        """The first tick the log holds (a keyframe): 0, or later for a log that starts with the
        fleet as it is at a later tick (a rotated segment, a worker's takeover, a cut)."""
        return int(self.scenario.start_tick)

    @property
    def open_ended(self) -> bool:
        """The run had no set end (a live service): its end is the summary's last tick."""
        return bool(self.scenario.open_ended)

    def is_keyframe_tick(self, tick: int) -> bool:
        """Whether the writer made ``tick`` a keyframe (the ticks = phase mod the interval, and
        the log's first tick)."""
        return tick == self.start_tick or keyframe_due(tick, self.keyframe_interval,
                                                       self.keyframe_phase)

    def keyframe_at_or_before(self, tick: int) -> int:
        """The keyframe a replay of ``tick`` starts from (never before the log's first tick)."""
        behind = (tick - self.keyframe_phase) % self.keyframe_interval
        return max(self.start_tick, tick - behind)

    def tick_time_ns(self, tick: int) -> int:
        return tick * int(round(self.scenario.dt_s * 1e9))

    def ticks(self, first: int | None = None, last: int | None = None) -> Iterator[TickData]:
        """The tick records, optionally only ticks first..last (found through the chunk index,
        without reading the rest of the file)."""
        start = None if first is None else self.tick_time_ns(first)
        end = None if last is None else self.tick_time_ns(last)
        dt_ns = self.tick_time_ns(1)
        ships = len(self.scenario.ship_ids)
        fmt = self.scenario.log_format_version
        table = len(self.ship_table()) if fmt >= 3 else ships
        limit = self.max_tick_bytes()
        grow = self._fleet_bound()
        for _topic, t_ns, data in iter_messages(self._file, str(self.path), {TOPIC_TICKS}, start,
                                                end, self.status, walk=self._walk, grow=grow):
            if t_ns % dt_ns:
                raise LogError(f"{self.path}: a tick record at {t_ns} ns, not on the tick")
            if len(data) > limit:
                raise self._oversize(t_ns // dt_ns, len(data))
            yield TickData(data, t_ns // dt_ns, str(self.path), ships, fmt, table)

    def max_tick_bytes(self) -> int:
        """The most bytes a tick record of this log can hold: every ship the log ever held
        (its header's and each that joined), each with every field (sim.fields), with margin."""
        ships = len(self.ship_table()) if self.log_format >= 3 else len(self.scenario.ship_ids)
        return tick_bytes_bound(ships)

    def _oversize(self, tick: int, size: int) -> LogError:
        ships = len(self.ship_table()) if self.log_format >= 3 else len(self.scenario.ship_ids)
        return LogError(f"{self.path}: tick {tick}: a tick record of {size:,} bytes, more than "
                        f"the log's {ships:,} ship(s) can fill ({self.max_tick_bytes():,}); "
                        f"refusing it")

    def _tick_limits(self) -> ReadLimits:
        """The reader's limits for the tick records: a chunk may hold at most what a writer puts
        in one (its target size, then one message more: the largest tick this fleet fills, or
        the log's header), so a chunk claiming more is refused before it is decompressed. The
        header's chunk, if not yet read in full, is read within them first."""
        ships = len(self.ship_table()) if self.log_format >= 3 else len(self.scenario.ship_ids)
        limits = self._limits_for(ships)
        self._check_header_chunk(limits)
        return limits

    def _limits_for(self, ships: int) -> ReadLimits:
        """_tick_limits for a fleet of ``ships`` ships (the log's records read so far)."""
        base = ReadLimits.from_environment()
        bound = self._chunk_bytes_for(ships)
        if bound >= base.max_chunk_bytes:
            return base
        return dataclasses.replace(base, max_chunk_bytes=bound, chunk_bound=(
            f"what a chunk of ticks of this log's {ships:,} ship(s) can hold"))

    def _chunk_bytes_for(self, ships: int) -> int:
        """The most a chunk of a fleet of ``ships`` ships holds: what the writer fills (its chunk
        size, and the schemas and channels a first chunk opens with), then one record more: the
        largest tick that fleet fills, or the log's largest record read so far."""
        return (CHUNK_BYTES_MAX + max(tick_bytes_bound(ships), self._largest_record)
                + CHUNK_SLACK_BYTES)

    def blocks(self, first: int | None = None, last: int | None = None,
               wanted: tuple[str, ...] | None = None, block_bytes: int = 32 << 20,
               reuse: bool = False, events: list | None = None) -> Iterator[TickBlock]:
        """The tick records (optionally ticks first..last) as columns, about ``block_bytes`` of
        records at a time, each chunk's records decoded as it is read and each block checked as
        a whole (logs.decode.BlockDecoder); ``wanted``: the fields to gather (default all).
        ``reuse``: every block's columns in the same buffers, valid until the next block is
        asked for (a reader that converts or copies each block at once saves the fresh pages'
        faults). ``events``: a list the event records of the same ticks are appended to (as
        bytes), read in the same pass (they lie in the same chunks: a second pass would
        decompress them again)."""
        start = None if first is None else self.tick_time_ns(first)
        end = None if last is None else self.tick_time_ns(last)
        dt_ns = self.tick_time_ns(1)
        fmt = self.log_format
        table = len(self.ship_table()) if fmt >= 3 else len(self.scenario.ship_ids)
        limit = self.max_tick_bytes()
        columns = {} if reuse else None

        def decoder() -> BlockDecoder:
            return BlockDecoder(fmt, table, len(self.scenario.ship_ids), wanted, str(self.path),
                                columns if reuse else None, block_bytes)

        # the records are decoded where they lie, in their decompressed chunk, a chunk at a time
        # (its buffer is then decompressed into again: ChunkBuffers)
        buffers = ChunkBuffers()
        dec = decoder()
        base = base_arr = None
        begins: list[int] = []
        ends: list[int] = []
        times: list[int] = []
        size = 0

        def feed() -> None:
            if begins:
                dec.add(base_arr, begins, ends, np.asarray(times, np.int64) // dt_ns)
                begins.clear(), ends.clear(), times.clear()

        topics = {TOPIC_TICKS} if events is None else {TOPIC_TICKS, TOPIC_EVENTS}
        grow = self._fleet_bound()
        for topic, t_ns, data in iter_messages(self._file, str(self.path), topics, start,
                                               end, self.status, views=True, walk=self._walk,
                                               buffers=buffers, grow=grow):
            owner = data.obj if isinstance(data, memoryview) else data
            if owner is not base:  # the next chunk: the last one's records are decoded
                feed()
                if base is not None:
                    buffers.give(base)
                base = owner
                base_arr = np.frombuffer(owner, np.uint8)
            if topic == TOPIC_EVENTS:
                events.append(bytes(data))
                continue
            if t_ns % dt_ns:
                raise LogError(f"{self.path}: a tick record at {t_ns} ns, not on the tick")
            n = len(data)
            if n > limit:
                raise self._oversize(t_ns // dt_ns, n)
            at = np.frombuffer(data, np.uint8).ctypes.data - base_arr.ctypes.data if n else 0
            begins.append(at)
            ends.append(at + n)
            times.append(t_ns)
            size += n
            if size >= block_bytes:
                feed()
                yield dec.finish()
                dec, size = decoder(), 0
        feed()
        if dec.messages:
            yield dec.finish()

    @property
    def log_format(self) -> int:
        return int(self.scenario.log_format_version)

    def ship_table(self) -> ShipTable:
        """Every ship of the log by key: the header's, then each that joined (format 3).

        The fleet records are read within what the fleet read so far bounds (_limits_for; a
        GrowingBound): a chunk over it is read as a stream, and if its last record runs past
        what a writer fills before it closes a chunk (a tick of ships that joined in it, or a
        crafted record) it is not inflated, unless it is a fleet record (checked as it
        arrives: _FieldCheck); such a chunk, and the header's if its check waits for the
        fleet (_check_header_chunk), is then read in full within the whole fleet's bound, or,
        one ending in a tick's commands (which the fleet does not bound), as every read after
        the fleet's reads it (_fleet_bound: the batch passed over, checked as it arrives)."""
        if getattr(self, "_table", None) is None:
            table = ShipTable(self.scenario.ship_ids, self.scenario.player_ids)
            self._fleet: list[pb.FleetChange] = []
            if self.log_format >= 3:
                where = str(self.path)
                general = ReadLimits.from_environment().max_chunk_bytes
                known: list = [None, 0]  # (ships, largest record), and the bound they give

                def bound() -> int:  # _limits_for's, once per change (it is asked per chunk)
                    if known[0] != (len(table), self._largest_record):
                        known[:] = [(len(table), self._largest_record),
                                    min(general, self._chunk_bytes_for(len(table)))]
                    return known[1]
                grow = GrowingBound(
                    bound=bound,
                    prefix=CHUNK_BYTES_MAX + CHUNK_SLACK_BYTES, held=MAX_SCENARIO_RECORD_BYTES,
                    check=lambda topic: _FieldCheck(f"{where}: damaged fleet record",
                                                    _FieldCheck.FLEET_CHANGE))
                for _topic, _t, data in iter_messages(self._file, where, {TOPIC_FLEET}, None,
                                                      None, self.status, walk=self._walk,
                                                      grow=grow):
                    self._largest_record = max(self._largest_record, len(data))
                    change = _parse(pb.FleetChange, data, f"{self.path}: damaged fleet record")
                    for j in change.joined:
                        try:
                            spec = json.loads(j.spec_json)
                        except (ValueError, RecursionError):
                            spec = None
                        if (not isinstance(spec, dict) or spec.get("id") != j.ship_id
                                or j.ship_id in table or j.ship_key != len(table)):
                            raise LogError(f"{self.path}: tick {change.tick}: a joining ship's "
                                           f"record is damaged (ship {j.ship_id!r})")
                        table.add(int(change.tick), spec)
                    self._fleet.append(change)
                limits = self._limits_for(len(table))
                final = self._grow_for(limits, table.ids) if grow.deferred else None
                for offset, _declared, topic, cid in grow.deferred:
                    if topic == TOPIC_COMMANDS:  # (the fleet does not bound a tick's commands)
                        chunk_checked_at(self._file, offset, where, final, {cid: topic})
                    else:
                        chunk_at(self._file, offset, where, limits)
                    if self._header_chunk is not None and self._header_chunk[0] == offset:
                        self._header_chunk = None  # (just read in full)
                self._check_header_chunk(limits, table.ids)
            self._table = table
        return self._table

    def timeline(self) -> Timeline:
        """The run's recorded input: the ships that joined and left, and every command
        (format 3). Read once (a later call, e.g. while the ticks are being read, reads nothing:
        a file whose footer is missing is read in one pass at a time). The commands are held in
        ~140 bytes each at the read's peak (RSS) when they repeat their values (a tick, a ship,
        a throttle or rcs held once: _Shared), ~390 when every value differs (before: 564 and
        594); each batch is parsed where it lies, a megabyte at a time (_command_pieces), and
        refused past TOUCHDOWN_MAX_COMMANDS before it is parsed."""
        if getattr(self, "_timeline", None) is None:
            self._timeline = self._read_timeline()
        return self._timeline

    def _read_timeline(self) -> Timeline:
        table = self.ship_table()
        self._header_chunk_checked()
        spawns, retires = [], []
        for change in self._fleet:
            for j in change.joined:
                spawns.append(Spawn(int(change.tick), table.specs[j.ship_key]))
            for sid in change.left_ship_id:
                retires.append(Retire(int(change.tick), sid))
        commands: list = []
        most = ReadLimits.from_environment().max_commands
        shared = _Shared({sid: sid for sid in table.ids} if self.log_format >= 3 else {})
        what = f"{self.path}: damaged command record"
        # each batch read where it lies, in its decompressed chunk (not copied out of it)
        for _topic, _t, data in iter_messages(self._file, str(self.path), {TOPIC_COMMANDS},
                                              None, None, self.status, views=True,
                                              walk=self._walk, grow=self._fleet_bound()):
            if len(commands) + _commands_at_most(data, most - len(commands) + 1) > most:
                raise LogError(f"{self.path}: more than {most:,} commands "
                               f"(TOUCHDOWN_MAX_COMMANDS); refusing to hold them")
            # a piece at a time (its parsed messages dropped before the next is parsed); a
            # refused command is said once the whole batch has parsed, damage first, as when
            # the batch was parsed whole
            refused = None
            for piece in _command_pieces(data):
                if refused is None:
                    refused = _add_commands(_parse(pb.CommandBatch, piece, what), shared,
                                            commands)
                else:
                    _parse(pb.CommandBatch, piece, what)
            if refused is not None:
                raise LogError(f"{self.path}: {refused}")
        data = piece = None  # (the last batch's bytes, not held while the timeline is made)
        return Timeline.of(spawns, retires, commands)

    def events(self, read: list[bytes] | None = None) -> Iterator[pb.TransitionEvent]:
        """The event records, in log order (``read``: those already read, by blocks' ``events``,
        rather than the log's)."""
        if read is None:
            self._header_chunk_checked()
        source = read if read is not None else (data for _t, data in self._iter({TOPIC_EVENTS}))
        for data in source:
            try:
                yield pb.TransitionEvent.FromString(data)
            except Exception as exc:
                raise LogError(f"{self.path}: damaged event record ({exc})") from None

    def read_summary(self) -> pb.LogSummary | None:
        self._header_chunk_checked()
        for _topic, data in self._iter({TOPIC_SUMMARY}):
            try:
                self.summary = pb.LogSummary.FromString(data)
            except Exception as exc:
                raise LogError(f"{self.path}: damaged summary record ({exc})") from None
        return self.summary

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> "LogReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class _FieldCheck:
    """A record (a protobuf message) checked as it is inflated, a piece at a time
    (GrowingBound's check; each call is given the bytes that came after the last's): each
    field's number, wire type and, for the fields ``longest`` names, length, as they arrive, so
    that bytes that cannot be one (a run of zeros, noise) are refused at their first piece, not
    held (or inflated) to the length their record declares. ``wire``: field number -> the wire
    types it may take."""

    #: FleetChange: tick, joined, left_ship_key (packed or not), left_ship_id
    FLEET_CHANGE = {1: (0,), 2: (2,), 3: (0, 2), 4: (2,)}
    #: CommandBatch: tick, commands
    COMMAND_BATCH = {1: (0,), 2: (2,)}

    def __init__(self, what: str, wire: dict[int, tuple[int, ...]],
                 longest: dict[int, int] | None = None):
        self.what = what
        self.wire = wire
        self.longest = longest or {}
        self.state = 0  # reading: 0 a field's key, 1 a varint's value, 2 a length
        self.field = self.value = self.shift = 0
        self.skip = 0  # bytes of a length-delimited field still to pass

    def __call__(self, data, final: bool) -> None:
        i, n = 0, len(data)
        while i < n:
            if self.skip:
                k = min(self.skip, n - i)
                self.skip -= k
                i += k
                continue
            b = data[i]
            i += 1
            self.value |= (b & 0x7F) << self.shift
            self.shift += 7
            if b & 0x80:
                if self.shift >= 70:
                    raise LogError(f"{self.what} (a varint of more than 10 bytes)")
                continue
            v, self.value, self.shift = self.value, 0, 0
            if self.state == 0:
                if (v & 7) not in self.wire.get(v >> 3, ()):
                    raise LogError(f"{self.what} (field {v >> 3}, wire type {v & 7})")
                self.field, self.state = v >> 3, 1 if v & 7 == 0 else 2
            elif self.state == 1:
                self.state = 0
            else:
                most = self.longest.get(self.field)
                if most is not None and v > most:
                    raise LogError(f"{self.what} (field {self.field} of {v:,} bytes, more than "
                                   f"{most:,})")
                self.skip, self.state = v, 0
        if final and (self.state or self.skip or self.shift):
            raise LogError(f"{self.what} (it ends inside a field)")


#: the most bytes a Command holds, less its ship id's: its fields' keys, a tick and a hold
#: (varints of 10 bytes at most), the id's length, a throttle and three rcs numbers (packed or
#: not), with margin
COMMAND_BYTES_BUT_ID = 128


def _commands_at_most(data, most: int) -> int:
    """How many commands a CommandBatch's bytes hold, or ``most`` if at least that many: each
    begins with the key of field 2 (0x12), so a batch holding fewer of those bytes than ``most``
    is counted no further (memchr's speed); else its fields are walked, at most ``most`` + 1 of
    them (a batch holds one tick, then its commands). So a batch is never parsed, nor its
    commands made, past what a timeline may hold."""
    keys = sum(bytes(data[i:i + COMMAND_PIECE_BYTES]).count(0x12)  # (a view: a piece at a time)
               for i in range(0, len(data), COMMAND_PIECE_BYTES))
    if keys < most:
        return keys
    i, n, fields, count = 0, len(data), 0, 0
    while i < n and count < most and fields <= most:
        key, i, err = varint(data, i, n)
        fields += 1
        if not err and key & 7 == 0:
            _, i, err = varint(data, i, n)
        elif not err and key & 7 == 2:
            length, i, err = varint(data, i, n)
            i += length
            count += key >> 3 == 2
        if err or key & 7 not in (0, 2):
            return count  # (damage: the parse says so)
    return most if fields > most else count


#: a command batch larger than this is parsed this many bytes at a time (_command_pieces)
COMMAND_PIECE_BYTES = 1 << 20
#: the most values _Shared holds: what a log's values may grow it to, however many differ
SHARED_MAX = 1 << 16
_ZERO, _MINUS_ZERO = 0.0, -0.0


def _command_pieces(data, piece: int = COMMAND_PIECE_BYTES) -> Iterator:
    """A CommandBatch's bytes as views of about ``piece`` bytes each (the batch itself if no
    larger), each ending where one of its fields does: a batch's parse is its pieces' parses
    merged (its commands, a repeated field, appended in order), each piece's messages held only
    while it is read, not the whole batch's (a million commands: ~45 MB of bytes, parsed ~1 MB
    at a time). Where the fields cannot be walked (damage) the rest is one piece, whose parse
    says what is wrong as the whole batch's would."""
    n = len(data)
    if n <= piece:
        yield data
        return
    view = memoryview(data)
    start = i = 0
    while i < n:
        if data[i] == 0x12 and i + 1 < n and data[i + 1] < 0x80:  # a command of < 128 bytes
            j, err = i + 2 + data[i + 1], 0
        else:
            key, j, err = varint(data, i, n)
            wire = key & 7
            if err or not 0 < key >> 3 < 1 << 29 or wire not in (0, 1, 2, 5):
                break
            if wire == 0:
                _, j, err = varint(data, j, n)
            elif wire == 2:
                length, j, err = varint(data, j, n)
                j += length
            else:
                j += 8 if wire == 1 else 4
        if err or j > n:
            break
        i = j
        if i - start >= piece:
            yield view[start:i]
            start = i
    if start < n:
        yield view[start:]


class _Shared:
    """The values of a log's commands, each held once however many commands give it (a tick,
    a ship id, a number, a vector): a command made from a record (a protobuf message) would
    otherwise hold its own copy of each (1 M commands of one tick: ~200 MB more). At most
    ``most`` values are held (a log of all different values holds its own copies past them).
    A number is shared by its bits: 0.0 and -0.0, equal as dict keys, are kept apart (replay
    is bit for bit)."""

    def __init__(self, ids: dict[str, str], most: int = SHARED_MAX):
        self.room = most
        self.ids = ids  # the log's ship ids (format 3), outside the bound (the table holds them)
        self.ticks: dict[int, int] = {}
        self.names: dict[str, str] = {}  # ship ids not in ``ids``
        self.numbers: dict[float, float] = {}  # (never a zero: see number)
        self.vectors: dict[bytes, tuple] = {}  # keyed by their numbers' bits

    def _hold(self, table: dict, key, x):
        """``x``, kept in ``table`` under ``key`` while there is room (a value not yet held:
        the lookups stay in the callers, where most values are found)."""
        if self.room > 0:
            table[key] = x
            self.room -= 1
        return x

    def tick(self, x: int) -> int:
        got = self.ticks.get(x)
        return self._hold(self.ticks, x, x) if got is None else got

    def ship_id(self, x: str) -> str:
        got = self.ids.get(x)
        if got is None:
            got = self.names.get(x)
            if got is None:
                return self._hold(self.names, x, x)
        return got

    def number(self, x: float) -> float:
        if x == 0.0:  # 0.0 == -0.0, one key: each is its own constant
            return _MINUS_ZERO if math.copysign(1.0, x) < 0 else _ZERO
        got = self.numbers.get(x)  # (a NaN is never found: held as it is, the check refuses it)
        return self._hold(self.numbers, x, x) if got is None else got

    def vector(self, x) -> tuple:
        if len(x) != 3:
            return tuple(x)  # (the check refuses it)
        key = _VECTOR.pack(*x)
        got = self.vectors.get(key)
        if got is None:
            a, b, c = x
            return self._hold(self.vectors, key,
                              (self.number(a), self.number(b), self.number(c)))
        return got


_VECTOR = struct.Struct("<3d")


def _add_commands(batch, shared: _Shared, commands: list) -> CommandError | None:
    """``batch``'s commands (a CommandBatch, parsed) appended to ``commands``, each checked, their
    values shared (_Shared); the first refused, if one is, instead of the rest."""
    made = [(f.name, shared.number if f.per_ship == 1 and f.choices is None else
             int if f.choices is not None else shared.vector) for f in fields.INPUTS]
    for c in batch.commands:
        try:
            commands.append(Command(shared.tick(int(c.tick)), shared.ship_id(c.ship_id),
                                    *[make(getattr(c, name)) for name, make in made]).check())
        except CommandError as exc:
            return exc
    return None


def _parse(cls, data: bytes, what: str):
    try:
        return cls.FromString(data)
    except Exception as exc:  # protobuf's DecodeError and friends
        raise LogError(f"{what} ({type(exc).__name__})") from None


__all__ = ["LogReader", "TickData", "MAX_START_TICK", "MIN_DT_S", "MAX_DT_S", "MAX_SHIPS",
           "MAX_SCENARIO_CHARS"]

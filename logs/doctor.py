"""``touchdown doctor``: a log's MCAP structure, every record held to the MCAP specification as
``mcap doctor`` holds it and more strictly (logs.examine), then what Touchdown itself checks of
its content (logs.reader)."""
from __future__ import annotations

import time

from touchdown.logs import LogError
from touchdown.logs.examine import Examination, examine
from touchdown.logs.header import TOPIC_SCENARIO
from touchdown.logs.reader import LogReader
from touchdown.logs.shards import take_of


def _structure_line(x: Examination) -> str:
    chunks = len(x.chunks)
    readable = sum(c.readable for c in x.chunks)
    mi = x.records.get("message index", 0)
    summary = sum(x.records.get(k, 0) for k in ("schema", "channel", "chunk index",
                                                  "attachment index", "metadata index",
                                                  "statistics", "summary offset")) \
        if x.data_end >= 0 else 0
    return (f"  structure: {chunks} chunk(s) ({readable} decompressed, CRC checked), "
            f"{x.messages:,} message(s), {mi} message index record(s) ({x.index_entries:,} "
            f"entries checked against their chunks), data end "
            f"{'at byte ' + format(x.data_end, ',') if x.data_end >= 0 else 'not found'} "
            f"(data section CRC {x.data_crc}); summary {summary} record(s), its CRC "
            f"{x.summary_crc}; footer {'ok' if x.footer and not _in(x, 'footer') else 'damaged or missing'}; "
            f"summary {'ok' if x.footer and not _in(x, 'summary', 'summary offsets', 'statistics') else 'damaged or missing'}")


def _in(x: Examination, *parts: str) -> bool:
    return any(f.part in parts for f in x.errors)


def report(path: str) -> tuple[list[str], bool]:
    """``touchdown doctor``: the structure (logs.examine: every record, every chunk decompressed
    and its CRC checked, its times against its messages, the message indexes entry by entry,
    the chunk indexes, statistics, summary offsets, footer, the data section's and the
    summary's CRCs), then what Touchdown itself checks of the content (its scenario record,
    every tick record decoded and checked, the events, the summary record). Returns (lines,
    whether anything is wrong: an error, not a warning)."""
    lines = []
    with open(path, "rb") as f:
        x = examine(f, path)
    lines.append(f"{path}: {x.size:,} bytes")
    lines.append(_structure_line(x))
    for finding in x.errors + x.warnings:
        lines.append(f"  {finding.line()}")
    bad = bool(x.errors)
    if x.data_crc == "absent":
        lines.append("  note: no data section CRC (written before the flight log had one): a changed byte "
                     "outside the chunks would go unnoticed")
    if any(f.part == "magic" for f in x.errors):
        lines.append("  verdict: damaged (not an MCAP file)")
        return lines, True
    if x.topics and TOPIC_SCENARIO not in x.topics:  # any MCAP file: its structure is all
        lines.append(f"  content: not a Touchdown log (topics: {', '.join(sorted(x.topics))}); "
                     f"its structure is what was checked")
        lines.append("  verdict: " + ("structure damaged" if bad else "ok"))
        return lines, bad
    try:
        with LogReader(path) as r:
            sr = r.scenario
            ticks = rows = 0
            last = None
            for b in r.blocks(wanted=("surface_state",)):
                ticks += b.ticks.shape[0]
                rows += b.rows
                last = int(b.ticks[-1])
            events = sum(1 for _ in r.events())
            summary = r.read_summary() if r.status.complete else None
            lines.append(f"  content: touchdown {sr.project_version}, log format "
                         f"{sr.log_format_version}, scenario {sr.name!r}, {len(r.ship_table())} "
                         f"ship(s); {ticks:,} tick record(s) ({rows:,} ship-ticks) decoded and "
                         f"checked, {r.start_tick}..{last}; {events:,} event(s); summary "
                         + ("none (the log was cut)" if summary is None else
                            f"last tick {summary.last_tick}, "
                            f"{'complete' if summary.complete else 'incomplete'}"
                            f"{', ' + summary.reason if summary.reason else ''}"))
            shard = []  # a live shard's file: its take and its mark (logs.shards)
            take = take_of(sr)
            if take is not None:
                shard.append(f"{take.shard}, take {take.epoch} (granted {_utc(take.taken_us)} "
                             f"by Redis's clock: of the shard's files, a later take's first "
                             f"tick ends this one's run, logs.shards)")
            if summary is not None and summary.HasField("superseded_after_tick"):
                shard.append(f"superseded after tick {summary.superseded_after_tick} (its "
                             f"worker lost the shard)")
            if shard:
                lines.append("  shard: " + "; ".join(shard))
            if not r.status.complete:
                bad = True
                lines.append(f"  problem: the log ends without a footer: its content was read "
                             f"up to the damage ({r.status.damage or 'the end of the file'}); "
                             f"`touchdown recover` rewrites it whole")
            lines.append("  verdict: " + ("structure damaged, content readable: `touchdown "
                                          "replay --verify` checks every number, `touchdown "
                                          "recover` rewrites the file whole"
                                          if bad else "ok"))
    except LogError as exc:
        lines.append(f"  content: unreadable: {str(exc).removeprefix(path + ': ')}")
        lines.append("  verdict: damaged")
        bad = True
    return lines, bad


def _utc(us: int) -> str:
    """Microseconds since 1970 as an ISO time, UTC, to the millisecond."""
    t = time.gmtime(us // 1_000_000)
    return time.strftime("%Y-%m-%dT%H:%M:%S", t) + f".{us // 1000 % 1000:03d}Z"


__all__ = ["report"]

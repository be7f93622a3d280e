"""``touchdown doctor``: a log's MCAP structure as ``mcap doctor`` reports it (logs.structure),
then what Touchdown itself checks of its content (logs.reader)."""
from __future__ import annotations

from touchdown.logs import LogError
from touchdown.logs.reader import LogReader
from touchdown.logs.structure import check, check_entries


def report(path: str) -> tuple[list[str], bool]:
    """``touchdown doctor``: the structure as ``mcap doctor`` reports it (records, chunks,
    message indexes, summary, footer; each index entry against its chunk), then what Touchdown
    itself checks of the content (its scenario record, every tick record decoded and checked,
    the events, the summary record). Returns (lines, whether anything is wrong)."""
    lines = []
    with open(path, "rb") as f:
        s = check(f)
        entries = check_entries(f, s, path) if s.chunks else 0
    lines.append(f"{path}: {s.size:,} bytes")
    lines.append(f"  structure: {len(s.chunks)} chunk(s), {s.message_indexes} message index "
                 f"record(s) ({entries:,} entries checked against their chunks), data end "
                 f"{'at byte ' + format(s.data_end, ',') if s.data_end >= 0 else 'not found'}; "
                 f"footer {'ok' if s.footer_ok else 'damaged or missing'}; summary "
                 f"{'ok' if s.summary_ok else 'damaged or missing'} ({s.summary_records} "
                 f"record(s), {s.chunk_indexes} chunk index(es))")
    for p in s.problems:
        lines.append(f"  problem: {p.part} at byte {p.where:,}: {p.what}")
    bad = bool(s.problems)
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
            if not r.status.complete:
                bad = True
                lines.append(f"  problem: the log ends without a footer: its content was read "
                             f"up to the damage ({r.status.damage or 'the end of the file'})")
            lines.append("  verdict: " + ("structure damaged, content readable: `touchdown "
                                          "replay --verify` checks every number"
                                          if bad else "ok"))
    except LogError as exc:
        lines.append(f"  content: unreadable: {str(exc).removeprefix(path + ': ')}")
        lines.append("  verdict: damaged")
        bad = True
    return lines, bad


__all__ = ["report"]

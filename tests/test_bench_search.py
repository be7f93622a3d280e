"""bench serve's search for the largest fleet (bench.serve.search): the rule that decides the
figure the README and the issue quote, checked on trials whose outcome is given (no service is
run: the trials' own measurement is bench serve's, not a test's)."""
from touchdown.bench.serve import search


def trials(capacity: int, noisy: dict[int, int] | None = None):
    """A fleet is kept up to ``capacity`` ships; ``noisy[n]``: the first that many trials of n
    ships fall behind anyway (a neighbour's burst). Returns run(n, seconds) and its log."""
    noisy = dict(noisy or {})
    log: list[tuple[int, float, bool]] = []

    def run(n: int, seconds: float) -> bool:
        ok = n <= capacity
        if ok and noisy.get(n, 0) > 0:
            noisy[n] -= 1
            ok = False
        log.append((n, seconds, ok))
        return ok
    return run, log


def test_one_noisy_trial_no_longer_caps_the_search():
    """A single late trial at 50,000 ships capped session 23's search below the 50,781 the same
    code kept; with a retry the search finds the capacity to its 3% precision."""
    run, _ = trials(52_000, noisy={50_000: 1})
    assert search(run, 12_500, 20.0, 400_000, retries=0) < 50_000
    run, log = trials(52_000, noisy={50_000: 1})
    found = search(run, 12_500, 20.0, 400_000, retries=1)
    assert 52_000 * 0.97 <= found <= 52_000
    assert [n for n, _, ok in log if not ok].count(50_000) == 1


def test_a_retry_never_keeps_a_fleet_that_falls_behind():
    """Above the capacity every trial fails, retried or not: the result never exceeds it, and
    the confirmation's long trial steps down while it fails."""
    for retries in (0, 1, 3):
        run, log = trials(30_000)
        found = search(run, 12_500, 20.0, 400_000, confirm_s=60.0, retries=retries)
        assert 30_000 * 0.97 <= found <= 30_000
        assert all(ok == (n <= 30_000) for n, _, ok in log)
        assert log[-1] == (found, 60.0, True)  # the confirmation ran at the size reported
        tries_at = [n for n, secs, _ in log if secs == 20.0]
        assert tries_at.count(50_000) == 1 + retries  # doubling 12,500 -> 25,000 -> 50,000


def test_no_fleet_kept_is_zero():
    run, _ = trials(0)
    assert search(run, 12_500, 20.0, 400_000, confirm_s=60.0) == 0

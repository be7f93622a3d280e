"""``touchdown sweep --chart PNG``: the envelope as a lander designer reads it.

A grid: the outcome over the first two varied keys, a colour per outcome with the boundaries
between outcomes drawn, small multiples over the third key (up to six of its values), each region
named where it is (no legend to hunt through). Landed cases are split by how far the footprint
slid: "stands" (under SLID_M) and "slides, then stands". Random samples (``--samples``): the
probability of a stable landing over the first two keys (binned), its 50% and 90% contours labelled
on the lines; with one key, that probability along it.
"""
from __future__ import annotations

import math

import numpy as np

#: Landed after sliding at least this far (m): drawn as its own region.
SLID_M = 0.5

#: The regions, in the order of their codes, with their colours (colour-blind safe, Okabe-Ito).
REGIONS = (("stands", "#009E73"), ("slides, then stands", "#56B4E9"), ("tips over", "#E69F00"),
           ("crashes", "#D55E00"), ("still moving", "#999999"), ("flying", "#F0E442"),
           ("missing", "#FFFFFF"))
CODE = {name: k for k, (name, _) in enumerate(REGIONS)}


def regions(outcome: list, slide: np.ndarray) -> np.ndarray:
    code = np.full(len(outcome), CODE["missing"], int)
    for i, o in enumerate(outcome):
        if o == "landed":
            code[i] = CODE["slides, then stands"] if slide[i] >= SLID_M else CODE["stands"]
        elif o == "tipped":
            code[i] = CODE["tips over"]
        elif o == "crashed":
            code[i] = CODE["crashes"]
        elif o == "contact":
            code[i] = CODE["still moving"]
        elif o == "flying":
            code[i] = CODE["flying"]
    return code


def _label(key: str) -> str:
    names = {"ships.initial.vertical_speed": "vertical speed (m/s)",
             "ships.initial.horizontal_speed": "sideways speed (m/s)",
             "ships.initial.tilt_deg": "tilt at touchdown (deg)",
             "body.terrain.slope_deg": "slope (deg)",
             "contact.friction_static": "static friction",
             "contact.friction_kinetic": "kinetic friction"}
    return names.get(key, key)


def draw(table, path, title: str | None = None) -> None:
    import json

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    meta = json.loads(table.schema.metadata[b"touchdown.sweep"])
    keys = [v.split("=")[0] for v in meta["vary"]]
    cols = {name: table.column(name).to_numpy(zero_copy_only=False) for name in keys}
    outcome = table.column("outcome").to_pylist()
    slide = table.column("slide_distance").to_numpy(zero_copy_only=False)
    slide = np.where(np.isnan(slide.astype(float)), 0.0, slide.astype(float))
    code = regions(outcome, slide)
    scen = json.loads(table.schema.metadata.get(b"touchdown.scenario", b"{}"))
    title = title or f"Touchdown envelope: {scen.get('name', '')}"
    if meta.get("samples"):
        fig = _probability(plt, keys, cols, code, title)
    else:
        fig = _grid(plt, keys, cols, code, title + f", {len(outcome):,} cases")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _grid(plt, keys, cols, code, title):
    xk = keys[0]
    yk = keys[1] if len(keys) > 1 else None
    zk = keys[2] if len(keys) > 2 else None
    zs = np.unique(cols[zk]) if zk else np.array([0.0])
    if len(zs) > 6:
        zs = zs[np.unique(np.round(np.linspace(0, len(zs) - 1, 6)).astype(int))]
    n = len(zs)
    ncol = min(n, 3)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.9 * nrow + 0.6), squeeze=False,
                             sharex=True, sharey=True, constrained_layout=True)
    from matplotlib.colors import BoundaryNorm, ListedColormap
    cmap = ListedColormap([c for _, c in REGIONS])
    norm = BoundaryNorm(np.arange(len(REGIONS) + 1) - 0.5, len(REGIONS))
    xs = np.unique(cols[xk])
    ys = np.unique(cols[yk]) if yk else np.array([0.0])
    for j, z in enumerate(zs):
        ax = axes[j // ncol][j % ncol]
        sel = cols[zk] == z if zk else np.ones(len(code), bool)
        img = np.full((len(ys), len(xs)), CODE["missing"])
        xi = np.searchsorted(xs, cols[xk][sel])
        yi = np.searchsorted(ys, cols[yk][sel]) if yk else np.zeros(int(sel.sum()), int)
        img[yi, xi] = code[sel]
        ax.pcolormesh(_edges(xs), _edges(ys), img, cmap=cmap, norm=norm, shading="flat")
        _boundaries(ax, xs, ys, img)
        _names(ax, xs, ys, img)
        if zk:
            ax.set_title(f"{_label(zk)} = {z:.3g}", fontsize=10)
        if j % ncol == 0:
            ax.set_ylabel(_label(yk) if yk else "")
        if j // ncol == nrow - 1:
            ax.set_xlabel(_label(xk))
    for j in range(n, nrow * ncol):
        axes[j // ncol][j % ncol].set_visible(False)
    fig.suptitle(title + f"  (slides: landed after {SLID_M:g} m or more of sliding)",
                 fontsize=11)
    return fig


def _edges(v):
    if len(v) == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    mid = (v[1:] + v[:-1]) / 2
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def _boundaries(ax, xs, ys, img):
    """A black line along every cell edge between two outcomes."""
    ex, ey = _edges(xs), _edges(ys)
    segs = []
    for i in range(img.shape[0]):
        for j in range(img.shape[1] - 1):
            if img[i, j] != img[i, j + 1]:
                segs.append([(ex[j + 1], ey[i]), (ex[j + 1], ey[i + 1])])
    for i in range(img.shape[0] - 1):
        for j in range(img.shape[1]):
            if img[i, j] != img[i + 1, j]:
                segs.append([(ex[j], ey[i + 1]), (ex[j + 1], ey[i + 1])])
    if segs:
        from matplotlib.collections import LineCollection
        ax.add_collection(LineCollection(segs, colors="black", linewidths=1.2))


def _names(ax, xs, ys, img):
    """Each outcome's name at the cell of its largest region farthest from any other outcome;
    an outcome of a few scattered cases (under 1% of the panel) is marked x at each and named in
    the panel's corner instead."""
    rare = []
    for k, (name, _) in enumerate(REGIONS):
        mask = img == k
        if not mask.any() or name == "missing":
            continue
        if mask.sum() < 0.01 * mask.size:
            ii, jj = np.nonzero(mask)
            ax.plot(xs[jj], ys[ii], "x", color="black", ms=5)
            rare.append(f"x {name}: {int(mask.sum())}")
            continue
        try:
            from scipy.ndimage import distance_transform_edt, label
            lab, nlab = label(mask)
            sizes = np.bincount(lab.ravel())[1:]
            big = 1 + int(np.argmax(sizes))
            d = distance_transform_edt(np.pad(lab == big, 1))[1:-1, 1:-1]
            i, j = np.unravel_index(int(np.argmax(d)), d.shape)
        except ImportError:
            ii, jj = np.nonzero(mask)
            i, j = int(np.median(ii)), int(np.median(jj))
        ax.text(xs[j], ys[i], name, ha="center", va="center", fontsize=9, weight="bold",
                bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="none", alpha=0.75))
    if rare:
        ax.text(0.02, 0.02, "; ".join(rare), transform=ax.transAxes, fontsize=8, va="bottom",
                bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="none", alpha=0.85))


def _probability(plt, keys, cols, code, title):
    landed = (code == CODE["stands"]) | (code == CODE["slides, then stands"])
    valid = code != CODE["missing"]
    xk = keys[0]
    x = cols[xk][valid].astype(float)
    ok = landed[valid]
    fig, ax = plt.subplots(figsize=(7.5, 5.2), constrained_layout=True)
    if len(keys) == 1:
        bins = np.linspace(x.min(), x.max(), 21)
        idx = np.clip(np.digitize(x, bins) - 1, 0, len(bins) - 2)
        n = np.bincount(idx, minlength=len(bins) - 1)
        k = np.bincount(idx, weights=ok, minlength=len(bins) - 1)
        p = np.where(n > 0, k / np.maximum(n, 1), np.nan)
        se = np.sqrt(p * (1 - p) / np.maximum(n, 1))
        mid = (bins[1:] + bins[:-1]) / 2
        ax.plot(mid, p, color="#009E73", lw=2)
        ax.fill_between(mid, p - 2 * se, p + 2 * se, color="#009E73", alpha=0.2)
        ax.text(mid[len(mid) // 2], min(1.0, np.nanmax(p)) + 0.02, "P(stable landing)",
                color="#009E73", ha="center")
        ax.set_ylim(0, 1.08)
        ax.set_xlabel(_label(xk))
        ax.set_ylabel("probability of a stable landing")
    else:
        yk = keys[1]
        y = cols[yk][valid].astype(float)
        nb = int(np.clip(np.sqrt(len(x) / 20), 4, 30))
        bx = np.linspace(x.min(), x.max(), nb + 1)
        by = np.linspace(y.min(), y.max(), nb + 1)
        n, _, _ = np.histogram2d(x, y, [bx, by])
        k, _, _ = np.histogram2d(x, y, [bx, by], weights=ok.astype(float))
        p = np.where(n > 0, k / np.maximum(n, 1), np.nan).T
        mesh = ax.pcolormesh(bx, by, p, cmap="RdYlGn", vmin=0, vmax=1, shading="flat")
        cx, cy = (bx[1:] + bx[:-1]) / 2, (by[1:] + by[:-1]) / 2
        if np.isfinite(p).sum() > 4:
            cs = ax.contour(cx, cy, np.nan_to_num(p, nan=0.0), levels=[0.5, 0.9],
                            colors="black", linewidths=[1.2, 2.0])
            ax.clabel(cs, fmt={0.5: "50% land", 0.9: "90% land"}, fontsize=9)
        cb = fig.colorbar(mesh, ax=ax)
        cb.set_label("probability of a stable landing (landed at the end)")
        ax.set_xlabel(_label(xk))
        ax.set_ylabel(_label(yk))
        others = ", ".join(_label(k) for k in keys[2:])
        if others:
            ax.set_title(f"over the other sampled keys: {others}", fontsize=9)
    fig.suptitle(title + f", {len(x):,} random cases (Latin hypercube)", fontsize=11)
    return fig

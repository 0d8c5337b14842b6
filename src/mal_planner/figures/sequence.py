"""The landing sequence as a time line: who lands when, each consecutive gap against the spacing it needs."""

from __future__ import annotations

from mal_planner.figures import style
from mal_planner.figures.data import GapView, LandingTimeline, PlanView, SlotView

style.apply_style()
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

NEEDED_COLOR = "#c8c8c8"
"""Sequence figure: the spacing a pair needs, a light band under the bracket of what it got."""
GAP_COLOR = "#404040"


def gap_label(g: GapView, pair: bool = True) -> str:
    """'B1→B3  100.0 ≥ 100.0 s  H→H 4 nm': the gap got against the spacing needed (and the wake pair)."""
    digits = 3 if g.short and g.needed is not None and f"{g.gap:.1f}" == f"{g.needed:.1f}" else 1
    text = f"{g.gap:.{digits}f} s" if g.needed is None else (
        f"{g.gap:.{digits}f} {'<' if g.short else '≥'} {g.needed:.{digits}f} s")
    if g.wake:
        text += f"  {g.wake.replace('->', '→')}" + ("" if g.wake_nm is None else f" {g.wake_nm:g} nm")
    if g.short:
        text += "  SHORT"
    return f"{g.leader}→{g.follower}  {text}" if pair else text


def _slot_label(s: SlotView) -> str:
    """'B1 (H)', 'A1 (M, fixed)': callsign, wake category and whether the landing time was fixed."""
    notes = [n for n in (s.wake_category, "fixed" if s.fixed else None) if n]
    return f"{s.callsign} ({', '.join(notes)})" if notes else s.callsign


def draw_sequence(ax, tl: LandingTimeline, colors: dict[str, str], pair_labels: bool = True) -> None:
    """Landing time line: a row per aircraft in landing order (earliest-to-landing bar, delay shaded, target |,
    landing v) and, between consecutive rows, a bracket of the gap got over a band of the spacing needed (red
    where short); the gap labels go in a column right of the axes."""
    row = {s.callsign: k for k, s in enumerate(tl.slots)}
    small = style.FONT_SIZE - 1.5
    for k, s in enumerate(tl.slots):
        c = colors.get(s.callsign, "0.3")
        if s.earliest is not None:
            ax.plot([min(s.earliest, s.landing_time), s.landing_time], [k, k], color=c, lw=1.2, alpha=0.7,
                    solid_capstyle="butt", zorder=2)
        if s.target is not None and s.landing_time > s.target:
            ax.barh(k, s.landing_time - s.target, left=s.target, height=0.36, color=c, alpha=0.28, lw=0, zorder=1)
        if s.target is not None:
            ax.plot(s.target, k, marker="|", ms=9, mew=1.6, color="0.15", ls="", zorder=4)
        ax.plot(s.landing_time, k, marker=style.MARKERS["land"], ms=7, color=c, mec="k", mew=0.5, ls="", zorder=5)
        if s.delay is not None and abs(s.delay) >= 0.05:
            ax.annotate(f"{s.delay:+.1f} s", (s.landing_time, k), xytext=(6, 0), textcoords="offset points",
                        va="center", ha="left", fontsize=small, color="0.35")
    for g in tl.gaps:
        if g.leader not in row or g.follower not in row:
            continue
        (t0, y0), (t1, y1) = ((tl.slots[row[cs]].landing_time, row[cs]) for cs in (g.leader, g.follower))
        y = (y0 + y1) / 2
        color = style.REQUIRED_COLOR if g.short else GAP_COLOR
        if g.needed is not None:
            ax.plot([t0, t0 + g.needed], [y + 0.14, y + 0.14], color=style.REQUIRED_COLOR if g.short else NEEDED_COLOR,
                    lw=4, alpha=0.35 if g.short else 1.0, solid_capstyle="butt", zorder=1)
        ax.plot([t0, t0], [y0, y], [t1, t1], [y, y1], color=color, lw=0.6, ls=":", zorder=2)
        ax.annotate("", xy=(t1, y), xytext=(t0, y), zorder=3,
                    arrowprops={"arrowstyle": "|-|, widthA=0.25, widthB=0.25", "color": color, "lw": 1.0,
                                "shrinkA": 0, "shrinkB": 0})
        ax.annotate(gap_label(g, pair_labels), (1.0, y), xycoords=("axes fraction", "data"), xytext=(6, 0),
                    textcoords="offset points", va="center", ha="left", fontsize=small, color=color,
                    fontweight="bold" if g.short else "normal", annotation_clip=False)
    n = len(tl.slots)
    ax.set_yticks(range(n), [_slot_label(s) for s in tl.slots])
    for label, s in zip(ax.get_yticklabels(), tl.slots, strict=True):
        label.set_color(colors.get(s.callsign, "0.3"))
        label.set_fontweight("bold")
    ax.set_ylim(max(n, 1) - 0.5, -0.5)
    ax.grid(False, axis="y")
    times = [t for s in tl.slots for t in (s.earliest, s.target, s.landing_time) if t is not None]
    times += [tl.slots[row[g.leader]].landing_time + g.needed for g in tl.gaps
              if g.needed is not None and g.leader in row]
    if times:
        lo, hi = min(times), max(times)
        span = max(hi - lo, 10.0)
        ax.set_xlim(lo - 0.04 * span, hi + 0.12 * span)  # room right for the delay labels
    ax.set_xlabel("time (s)")


def sequence_handles(tl: LandingTimeline) -> list:
    """Legend entries of the sequence figure (only what it draws)."""
    from matplotlib.patches import Patch

    slots = tl.slots
    handles = [Line2D([], [], color="0.3", marker=style.MARKERS["land"], mec="k", ls="", label="landing")]
    if any(s.earliest is not None for s in slots):
        handles.append(Line2D([], [], color="0.3", lw=1.2, label="earliest to landing"))
    if any(s.target is not None for s in slots):
        handles += [Line2D([], [], color="0.15", marker="|", ms=9, mew=1.6, ls="", label="target"),
                    Patch(color="0.3", alpha=0.28, lw=0, label="delay")]
    if any(g.needed is not None for g in tl.gaps):
        handles.append(Line2D([], [], color=NEEDED_COLOR, lw=4, label="spacing needed"))
    handles.append(Line2D([], [], color=GAP_COLOR, lw=1.0, marker="|", label="gap got"))
    if any(g.short for g in tl.gaps):
        handles.append(Line2D([], [], color=style.REQUIRED_COLOR, lw=1.0, marker="|", label="gap short"))
    return handles


def _label_column(tl: LandingTimeline, pair: bool, fontsize: float) -> float:
    """Width (inches) of the gap labels right of the sequence axes."""
    longest = max((len(gap_label(g, pair)) for g in tl.gaps), default=0)
    return (longest * 0.58 + 1.5) * fontsize / 72.0


def figure_sequence(view: PlanView, colors: dict[str, str]):
    """The landing sequence as a time line: who lands when, each consecutive gap against what it needs."""
    tl = view.timeline
    n = max(len(tl.slots), 1)
    column = _label_column(tl, True, style.FONT_SIZE - 1.5)
    width = max(style.WIDTH_IN, 4.8 + column)
    fig, ax = plt.subplots(figsize=(width, 1.7 + 0.45 * n))
    h = fig.get_figheight()
    left = (0.25 + max((len(_slot_label(s)) for s in tl.slots), default=4) * 0.08) / width
    fig.subplots_adjust(left=left, right=1.0 - (column + 0.15) / width, bottom=0.55 / h, top=1.0 - 0.85 / h)
    draw_sequence(ax, tl, colors)
    how = [tl.strategy] if tl.strategy else []
    how += [f"wake table {tl.wake_table}"] if tl.wake_table else []
    how += [f"total delay {tl.total_delay:.1f} s"] if tl.total_delay is not None else []
    short = sum(g.short for g in tl.gaps)
    how += [f"{short} gap{'s' if short > 1 else ''} short"] if short else []
    fig.suptitle(f"{view.name}: landing sequence" + (f" ({', '.join(how)})" if how else ""), y=1.0 - 0.08 / h,
                 va="top")
    handles = sequence_handles(tl)
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), bbox_to_anchor=(0.5, 1.0 - 0.32 / h),
               handlelength=1.6, columnspacing=1.2)
    return fig


def draw_sequence_panel(fig, cell, view: PlanView, colors: dict[str, str]) -> None:
    """The overview's time-line panel: the landing sequence in ``cell``, its gap labels in a column at its right."""
    tl = view.timeline
    column = _label_column(tl, False, style.FONT_SIZE - 1.5)
    cell_w = cell.get_position(fig).width * fig.get_figwidth()
    sub = cell.subgridspec(1, 2, width_ratios=[max(cell_w - column - 0.1, 1.0), column + 0.1], wspace=0.0)
    ax = fig.add_subplot(sub[0, 0])
    draw_sequence(ax, tl, colors, pair_labels=False)
    ax.set_xlabel("time (s)", labelpad=1)
    key = ["| target, shaded: delay"] if any(s.target is not None for s in tl.slots) else []
    key += [f"total {tl.total_delay:.1f} s"] if tl.total_delay is not None else []
    ax.set_title("Landing sequence" + (f" ({'; '.join(key)})" if key else ""))

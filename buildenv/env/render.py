"""What ``BuildingWeek-v0``'s ``render()`` shows: the last simulated week as a picture or a few lines of text.

A :class:`WeekFrame` holds what one week needs (its dates, the occupied hours, the outdoor temperature, and once
settings have been applied the indoor temperature, the setpoints and the HVAC energy with the week's scores);
:func:`rgb` draws it with matplotlib's Agg canvas (no window, no global pyplot state) into an ``(H, W, 3)``
``uint8`` array, :func:`ansi` writes it as text. Before the week is simulated (just after ``reset``) the frame
shows the week ahead: the site's outdoor temperature (the weather itself, not an observation's forecast noise)
against the comfort target.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field

import numpy as np

from buildenv import catalogue as cat

WIDTH_PX, HEIGHT_PX, DPI = 960, 540, 96


@dataclass(frozen=True)
class WeekFrame:
    """One week as ``render()`` shows it.

    Attributes:
        week: week of the site's year.
        monday: the week's Monday.
        step: weeks of the episode simulated so far (0 just after ``reset``).
        episode_weeks: weeks per episode.
        occupied: ``(168,)`` booleans, the occupied hours comfort is counted over.
        target_c: the comfort target T* (degC).
        band_k: half-width of the comfort band drawn around T* (K); 0 draws the target line only.
        outdoor_c: ``(168,)`` outdoor dry-bulb temperature (degC).
        temperature_c: ``(168,)`` indoor temperature (degC), None before the week is simulated.
        hvac_wh_m2: ``(168,)`` HVAC energy in each hour (Wh/m2), None before.
        heating_setpoint_c, cooling_setpoint_c: ``(168,)`` setpoints of the applied settings (degC), None before.
        scores: the week's step info values (``reward``, ``energy_term``, ``comfort_k``, ``energy_kwh``,
            ``energy_historical_kwh``, ``comfort_historical_k``, ``savings_percent``,
            ``mean_temperature_occupied_c``), empty before.
        comfort: the comfort measure's name (``rms``, ``band``, ``mean_abs``).
        site: the site's name where the environment runs several (a context set), else empty.
    """

    week: int
    monday: dt.date
    step: int
    episode_weeks: int
    occupied: np.ndarray
    target_c: float
    band_k: float
    outdoor_c: np.ndarray
    temperature_c: np.ndarray | None = None
    hvac_wh_m2: np.ndarray | None = None
    heating_setpoint_c: np.ndarray | None = None
    cooling_setpoint_c: np.ndarray | None = None
    scores: dict[str, float] = field(default_factory=dict)
    comfort: str = "rms"
    site: str = ""

    @property
    def simulated(self) -> bool:
        """Whether the frame holds a simulated week (False just after ``reset``)."""
        return self.temperature_c is not None

    def title(self) -> str:
        """``week 45, 2019-11-04 to 2019-11-10`` (with the episode's step; after ``site <name>, `` in a context
        set)."""
        last = self.monday + dt.timedelta(days=6)
        site = f"site {self.site}, " if self.site else ""
        return (
            f"{site}week {self.week}, {self.monday:%Y-%m-%d} to {last:%Y-%m-%d} (step {self.step}/{self.episode_weeks})"
        )


def _change(scores: dict[str, float]) -> str:
    """``12.5 % less than historical`` (or more) of a week's energy."""
    saved = scores["savings_percent"]
    return f"{abs(saved):.1f} % {'less' if saved >= 0 else 'more'} than historical"


def ansi(frame: WeekFrame | None) -> str:
    """A few lines on the week: dates, energy against the historical settings, comfort; ``""`` for None."""
    if frame is None:
        return ""
    head = f"BuildingWeek-v0 {frame.title()}"
    if not frame.simulated:
        mean = float(frame.outdoor_c.mean())
        return (
            f"{head}\nno settings applied yet; outdoor temperature mean {mean:.1f} degC, "
            f"comfort target {frame.target_c:.1f} degC\n"
        )
    s = frame.scores
    return (
        f"{head}\n"
        f"energy  {s['energy_kwh']:.1f} kWh vs {s['energy_historical_kwh']:.1f} kWh historical "
        f"(energy term {s['energy_term']:.3f}, {_change(s)})\n"
        f"comfort {s['comfort_k']:.2f} K {frame.comfort} from {frame.target_c:.1f} degC vs "
        f"{s['comfort_historical_k']:.2f} K historical (occupied mean {s['mean_temperature_occupied_c']:.1f} degC)\n"
        f"reward  {s['reward']:.3f}\n"
    )


def rgb(frame: WeekFrame) -> np.ndarray:
    """The week as an ``(540, 960, 3)`` ``uint8`` picture: temperatures (indoor, outdoor, setpoints, the comfort
    target) above, the HVAC energy below, occupied hours shaded green, the days' dates on the time axis."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from buildenv.plotting import shade_occupancy

    fig = Figure(figsize=(WIDTH_PX / DPI, HEIGHT_PX / DPI), dpi=DPI)
    canvas = FigureCanvasAgg(fig)
    ax_t, ax_q = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    hours = np.arange(cat.HOURS_PER_WEEK)
    for ax in (ax_t, ax_q):
        shade_occupancy(ax, frame.occupied.astype(float))
        ax.grid(alpha=0.3)
    if frame.band_k > 0:
        ax_t.axhspan(frame.target_c - frame.band_k, frame.target_c + frame.band_k, color="gold", alpha=0.2, lw=0)
    ax_t.axhline(frame.target_c, color="goldenrod", lw=1.2, label=f"comfort target {frame.target_c:.1f}")
    ax_t.plot(hours, frame.outdoor_c, color="tab:gray", lw=1, label="outdoor")
    if frame.simulated:
        ax_t.plot(hours, frame.temperature_c, color="black", lw=1.6, label="indoor")
        if frame.heating_setpoint_c is not None:
            ax_t.step(
                hours, frame.heating_setpoint_c, where="post", color="tab:red", lw=0.9, ls="--", label="heating sp"
            )
        if frame.cooling_setpoint_c is not None:
            ax_t.step(
                hours, frame.cooling_setpoint_c, where="post", color="tab:blue", lw=0.9, ls="--", label="cooling sp"
            )
        ax_q.fill_between(hours, frame.hvac_wh_m2, step="post", color="tab:orange", alpha=0.6, lw=0)
        ax_q.step(hours, frame.hvac_wh_m2, where="post", color="tab:orange", lw=1, label="HVAC energy")
        s = frame.scores
        subtitle = (
            f"energy {s['energy_kwh']:.0f} kWh ({_change(s)}), "
            f"comfort {s['comfort_k']:.2f} K ({s['comfort_historical_k']:.2f} K historical), reward {s['reward']:.3f}"
        )
    else:
        ax_q.text(0.5, 0.5, "no settings applied yet", ha="center", va="center", transform=ax_q.transAxes)
        subtitle = "the week ahead: outdoor temperature, no settings applied yet"
    ax_t.set_ylabel("temperature (degC)")
    ax_t.legend(loc="upper right", fontsize=7, ncol=5)
    ax_t.set_title(f"BuildingWeek-v0 {frame.title()}\n{subtitle}", fontsize=9)
    ax_q.set_ylabel("HVAC (Wh/m2 per h)")
    ax_q.set_xlim(0, cat.HOURS_PER_WEEK)
    ax_q.set_xticks(range(0, cat.HOURS_PER_WEEK + 1, cat.HOURS_PER_DAY))
    days = [frame.monday + dt.timedelta(days=d) for d in range(8)]
    ax_q.set_xticklabels([f"{d:%a %d %b}" for d in days], fontsize=8)
    ax_q.set_xlabel("green: occupied hours")
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()

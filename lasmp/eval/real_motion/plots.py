"""One figure per scenario: the platform's reference pose, linear acceleration and angular rate over time."""

from __future__ import annotations

from pathlib import Path

from lasmp.envs import trajectories as trj
from lasmp.io.atomic import atomic_write_with
from lasmp.motions.motion import Motion, derivatives


def plot_motion(m: Motion, path: Path) -> None:
    """Four stacked panels over t: position (m), attitude (rad), linear acceleration (m/s^2, world
    axes) and |omega| with the Euler-angle rates (rad/s)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    v, a = derivatives(m)
    t = m.t_s
    fig, axes = plt.subplots(4, 1, figsize=(9, 8.5), sharex=True)
    panels = (
        (axes[0], m.pose[:, :3], ("x", "y", "z"), "position (m)"),
        (axes[1], m.pose[:, 3:], ("roll", "pitch", "yaw"), "attitude (rad)"),
        (axes[2], a[:, :3], ("a_x", "a_y", "a_z"), "acceleration (m/s²)"),
        (axes[3], v[:, 3:], ("roll rate", "pitch rate", "yaw rate"), "angular rate (rad/s)"),
    )
    for ax, data, names, label in panels:
        for k, name in enumerate(names):
            ax.plot(t, data[:, k], lw=1.0, label=name)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper right", ncol=3)
    axes[3].plot(t, trj.angular_rate(m.pose, v), color="k", lw=0.8, label="|ω|")
    axes[3].legend(fontsize=8, loc="upper right", ncol=4)
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"{m.name}: platform reference motion", fontsize=11)
    fig.tight_layout()
    atomic_write_with(Path(path), lambda tmp: fig.savefig(tmp, dpi=90, format="png"))
    plt.close(fig)


def plot_all(motions: list[Motion], out_dir: Path) -> list[Path]:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for m in motions:
        paths.append(out_dir / f"{m.name}.png")
        plot_motion(m, paths[-1])
    return paths

"""Figures of the value functions: training loss, the paper's V̂ heatmap, V_s slices."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from madpinn.value_functions.validation import HEATMAP  # noqa: E402


PNG_DPI = 300                   # print resolution of the value-function figures' PNGs
HEATMAP_POINTS = 301            # ego positions per axis of the V̂ heatmap (smooth contours at print size)


def _save(fig, stem: Path) -> list[Path]:
    """``stem.pdf`` and ``stem.png`` (``PNG_DPI``; no creation date in the PDF, so a rerun leaves
    the committed files unchanged)."""
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    out = []
    for ext in (".pdf", ".png"):
        path = stem.with_suffix(ext)
        fig.savefig(path, dpi=PNG_DPI, bbox_inches="tight", metadata={"CreationDate": None} if ext == ".pdf" else None)
        out.append(path)
    plt.close(fig)
    return out


def loss_curve(history, title: str, path: Path) -> Path:
    h = np.asarray(history, dtype=float)
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.semilogy(np.arange(1, h.size + 1), h, lw=0.4, alpha=0.4, label="iteration")
    w = max(1, h.size // 100)
    if h.size >= w:
        smooth = np.convolve(h, np.ones(w) / w, mode="valid")
        ax.semilogy(np.arange(w, h.size + 1), smooth, lw=1.2, label=f"mean of {w}")
    ax.set_xlabel("iteration")
    ax.set_ylabel("HJB residual loss")
    ax.set_title(title)
    ax.legend()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


HEATMAP_CLIP_PERCENTILE = 95.0   # colour scale of the V̂ heatmap: up to this percentile of the feasible values


def value_heatmap(axis, z_star, feasible, stem: Path) -> list[Path]:
    """:func:`draw_value_heatmap`, saved as ``.pdf`` and ``.png`` at ``stem``."""
    return _save(draw_value_heatmap(axis, z_star, feasible), stem)


def draw_value_heatmap(axis, z_star, feasible):
    """Paper figure: V_d = z* over the ego position (``axis`` [P] m, ``z_star``, ``feasible`` [P, P]);
    infeasible (V̂(0, o, z_max) > 0) in grey. The colour scale ends at the
    ``HEATMAP_CLIP_PERCENTILE``-th percentile of the feasible values, so the few large values on
    the rims of the infeasible regions do not flatten the gradient toward the goal: larger values
    take the top colour (the colour bar's arrow says so); thin contours every step of the scale."""
    ax_np = axis.numpy()
    ok = feasible.numpy()
    z = np.where(ok, z_star.numpy(), np.nan)
    lo, hi = float(np.nanmin(z)), float(np.nanpercentile(z, HEATMAP_CLIP_PERCENTILE))
    zmax = float(np.nanmax(z))
    fig, ax = plt.subplots(figsize=(5.4, 4.5))
    im = ax.pcolormesh(ax_np, ax_np, z, cmap="viridis", vmin=lo, vmax=hi, shading="auto", rasterized=True)
    levels = matplotlib.ticker.MaxNLocator(8).tick_values(lo, hi)
    # contours only within the colour scale: the steep rims above it would pack every level into a white band
    ax.contour(ax_np, ax_np, np.where(z <= hi, z, np.nan), levels=levels, colors="white", linewidths=0.6, alpha=0.7)
    unsafe = np.ma.masked_where(ok, np.ones(z.shape))
    ax.pcolormesh(ax_np, ax_np, unsafe, cmap=matplotlib.colors.ListedColormap(["0.35"]), shading="auto", rasterized=True)
    ax.contour(ax_np, ax_np, ok.astype(float), levels=[0.5], colors="k", linewidths=1.0)
    cb = fig.colorbar(im, ax=ax, extend="max" if zmax > hi else "neither")
    cb.set_label(rf"$V_d = z^*$ (cost); scale clipped at the {HEATMAP_CLIP_PERCENTILE:g}th percentile"
                 "\n" + rf"({hi:.2f}; larger values, up to {zmax:.1f}, in the top colour)", fontsize=10)
    cb.ax.tick_params(labelsize=10)
    for (x, y), (gx, gy) in zip(HEATMAP["neighbours"], HEATMAP["neighbour_goals"]):
        ax.plot(x, y, "ko", ms=6)
        ax.annotate("", xy=(x + 0.25 * HEATMAP["neighbour_velocity"][0], y), xytext=(x, y),
                    arrowprops={"arrowstyle": "->", "color": "k", "lw": 1.2})
    ax.plot(*HEATMAP["ego_goal"], "*", color="white", mec="k", ms=15, label="ego goal")
    ax.set_xlabel("ego x (m)", fontsize=11)
    ax.set_ylabel("ego y (m)", fontsize=11)
    ax.tick_params(labelsize=10)
    ax.set_aspect("equal")
    ax.set_title(r"learned value, ego $v=[1,0]$ m/s; grey: $\hat V(0,o,z_{max})>0$", fontsize=10.5)
    ax.legend(loc="lower right", fontsize=9.5)
    return fig


def vs_slices_figure(axis, values, velocities, collision_radius: float, stem: Path) -> list[Path]:
    k = len(velocities)
    fig, axes = plt.subplots(1, k, figsize=(3.2 * k, 3.0), squeeze=False)
    ax_np = axis.numpy()
    vmax = float(np.nanmax(np.abs(values.numpy())))
    for a, vel, val in zip(axes[0], velocities, values.numpy()):
        im = a.pcolormesh(ax_np, ax_np, val, cmap="RdBu", vmin=-vmax, vmax=vmax, shading="auto", rasterized=True)
        a.contour(ax_np, ax_np, val, levels=[0.0], colors="k", linewidths=1.0)
        a.add_patch(plt.Circle((0, 0), collision_radius, fill=False, color="m", lw=0.8))
        a.set_title(f"v_rel = [{vel[0]:g}, {vel[1]:g}] m/s", fontsize=9)
        a.set_xlabel("p_x rel (m)")
        a.set_aspect("equal")
    axes[0][0].set_ylabel("p_y rel (m)")
    fig.colorbar(im, ax=axes[0].tolist(), label=r"$V_s(x, 0)$ (m); black: $V_s = 0$")
    return _save(fig, stem)


def validation_figure(model, kind: str, half_width: float, slice_velocities, z_tolerance: float, stem: Path) -> list[Path]:
    """The figure of a trained model: V̂ heatmap over an arena of ``half_width`` (m), z* on the
    deployed grid of ``z_tolerance``, or V_s slices at ``slice_velocities`` (m/s); ``.pdf`` and
    ``.png`` at ``stem``."""
    from madpinn.value_functions import validation

    if kind == "vhat":
        axis, z_star, feasible, _ = validation.heatmap_values(model, z_tolerance, half_width, HEATMAP_POINTS)
        return value_heatmap(axis, z_star, feasible, stem)
    axis, values = validation.vs_slices(model, slice_velocities)
    return vs_slices_figure(axis, values, slice_velocities, model.collision_radius, stem)


def vs_grid_figure(solution, vs, velocity, stem: Path) -> list[Path]:
    """:func:`draw_vs_grid`, saved as ``.pdf`` and ``.png`` at ``stem``."""
    return _save(draw_vs_grid(solution, vs, velocity), stem)


def draw_vs_grid(solution, vs, velocity):
    """Zero level sets of the grid reference (black) and of the PINN V_s (red, dashed) on the
    relative-position plane at the relative velocity nearest ``velocity`` (m/s), one panel per time."""
    import torch

    iv = [int(np.argmin(np.abs(solution.v_axis - c))) for c in velocity]
    p = solution.p_axis
    yy, xx = np.meshgrid(p, p, indexing="ij")
    x = np.stack([xx.ravel(), yy.ravel(), np.full(xx.size, solution.v_axis[iv[0]]),
                  np.full(xx.size, solution.v_axis[iv[1]])], -1)
    k = len(solution.times)
    fig, axes = plt.subplots(1, k, figsize=(2.9 * k, 3.2), squeeze=False, sharex=True, sharey=True)
    for ax, t, ref in zip(axes[0], solution.times, solution.values):
        pred = vs.value(torch.as_tensor(x, dtype=torch.float64), t=float(t)).double().cpu().numpy().reshape(yy.shape)
        ax.contour(p, p, ref[:, :, iv[0], iv[1]].T, levels=[0.0], colors="k")
        ax.contour(p, p, pred, levels=[0.0], colors="r", linestyles="--")
        ax.set_title(f"t = {t:g} s")
        ax.set_aspect("equal")
        ax.set_xlabel("p_x (m)")
        ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(4, symmetric=True))
        ax.yaxis.set_major_locator(matplotlib.ticker.MaxNLocator(4, symmetric=True))
        ax.tick_params(axis="x", labelsize=8)   # neighbouring panels' end labels must not meet
    axes[0][0].set_ylabel("p_y (m)")
    fig.tight_layout(w_pad=1.5, rect=(0, 0, 1, 0.93))
    fig.suptitle(f"V_s = 0: grid (black) vs PINN (red), v = ({solution.v_axis[iv[0]]:.2f}, {solution.v_axis[iv[1]]:.2f}) m/s",
                 fontsize=9)
    return fig

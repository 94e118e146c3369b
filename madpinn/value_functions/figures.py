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


VS_HALF_WIDTH = 1.2     # V_s figures show relative positions |p_x|, |p_y| ≤ this (m): every unsafe set of their velocities
VS_SLICE_POINTS = 241   # relative positions per axis of the V_s slices (1 cm)
VS_GRID_VELOCITIES = ((0.0, 0.0), (-1.5, 0.0), (-3.0, 0.0), (-2.0, -2.0))   # fig_vs_grid's panels (m/s), inside the grid's trusted |v| ≤ 3
VS_GRID_HALF_WIDTH = 0.6   # fig_vs_grid shows |p_x|, |p_y| ≤ this (m): the grid's trusted interior (config interior_p)


def _collision_disk(ax, radius: float):
    """The collision disk ‖p‖ = r (magenta): where ψ = ‖p‖ − r < 0, i.e. V_s < 0 at every velocity."""
    return ax.add_patch(plt.Circle((0, 0), radius, fill=False, color="m", lw=1.0, zorder=4))


def vs_slices_figure(axis, values, velocities, collision_radius: float, stem: Path) -> list[Path]:
    """:func:`draw_vs_slices`, saved as ``.pdf`` and ``.png`` at ``stem``."""
    return _save(draw_vs_slices(axis, values, velocities, collision_radius), stem)


def draw_vs_slices(axis, values, velocities, collision_radius: float):
    """V_s(x, 0) over the relative position (``axis`` [P] m, ``values`` [K, P, P], rows y) for each
    relative velocity (m/s), one panel each: colour diverging at 0 (red: V_s < 0, a pair that cannot
    avoid a collision within the horizon; blue: safe), the zero level set in black, the collision
    disk ‖p‖ = r in magenta."""
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.lines import Line2D

    k = len(velocities)
    fig, axes = plt.subplots(1, k, figsize=(3.0 * k, 3.6), squeeze=False, sharex=True, sharey=True,
                             gridspec_kw={"bottom": 0.22, "top": 0.9, "left": 0.06, "right": 0.9})
    ax_np, vals = axis.numpy(), values.numpy()
    norm = TwoSlopeNorm(vcenter=0.0, vmin=min(float(np.nanmin(vals)), -1e-3), vmax=max(float(np.nanmax(vals)), 1e-3))
    for a, vel, val in zip(axes[0], velocities, vals):
        im = a.pcolormesh(ax_np, ax_np, val, cmap="RdBu", norm=norm, shading="auto", rasterized=True)
        a.contour(ax_np, ax_np, val, levels=[0.0], colors="k", linewidths=1.2)
        _collision_disk(a, collision_radius)
        a.set_title(rf"$v_{{rel}}$ = ({vel[0]:g}, {vel[1]:g}) m/s", fontsize=10)
        a.set_xlabel(r"$p_x$ relative (m)")
        a.set_aspect("equal")
    axes[0][0].set_ylabel(r"$p_y$ relative (m)")
    cb = fig.colorbar(im, ax=axes[0].tolist(), label=r"$V_s(x, 0)$ (m)", shrink=0.85, pad=0.02)
    lo, hi = norm.vmin, norm.vmax                  # ticks on both sides of 0 (the two halves have their own scales)
    ticks = [*np.linspace(lo, 0.0, 3)[:-1], 0.0, *np.linspace(0.0, hi, 4)[1:]]
    cb.ax.yaxis.set_major_locator(matplotlib.ticker.FixedLocator(ticks))
    cb.ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%.2f"))
    handles = [Line2D([], [], color="k", lw=1.2, label=r"$V_s = 0$: boundary of the unsafe set (red inside)"),
               Line2D([], [], color="m", lw=1.0, label=rf"collision disk $\|p\| = r$ = {collision_radius:g} m")]
    fig.legend(handles=handles, loc="lower center", ncol=2, frameon=False, bbox_to_anchor=(0.45, 0.0), fontsize=9)
    return fig


def validation_figure(model, kind: str, half_width: float, slice_velocities, z_tolerance: float, stem: Path) -> list[Path]:
    """The figure of a trained model: V̂ heatmap over an arena of ``half_width`` (m), z* on the
    deployed grid of ``z_tolerance``, or V_s slices at ``slice_velocities`` (m/s); ``.pdf`` and
    ``.png`` at ``stem``."""
    from madpinn.value_functions import validation

    if kind == "vhat":
        axis, z_star, feasible, _ = validation.heatmap_values(model, z_tolerance, half_width, HEATMAP_POINTS)
        return value_heatmap(axis, z_star, feasible, stem)
    axis, values = validation.vs_slices(model, slice_velocities, VS_SLICE_POINTS, VS_HALF_WIDTH)
    return vs_slices_figure(axis, values, slice_velocities, model.collision_radius, stem)


def vs_grid_figure(solution, vs, velocities, stem: Path) -> list[Path]:
    """:func:`draw_vs_grid`, saved as ``.pdf`` and ``.png`` at ``stem``."""
    return _save(draw_vs_grid(solution, vs, velocities), stem)


def draw_vs_grid(solution, vs, velocities=VS_GRID_VELOCITIES):
    """Zero level sets of the grid reference (black) and of the PINN V_s (red, dashed) on the
    relative-position plane at t = 0 (the time the policy uses), one panel per relative velocity
    of ``velocities`` (m/s; the grid node nearest each), the PINN evaluated on a 1-cm grid. One panel per velocity, not per time: at
    these speeds the set is the same at every t of the grid (a pair escapes or collides within the
    last 0.25 s of the horizon), so panels over t would repeat each other."""
    import torch
    from matplotlib.lines import Line2D

    it = int(np.argmin(np.abs(np.asarray(solution.times, dtype=float))))
    t = float(solution.times[it])
    ref_t = solution.values[it]
    p = solution.p_axis
    fine = np.linspace(-VS_GRID_HALF_WIDTH, VS_GRID_HALF_WIDTH, VS_SLICE_POINTS)   # the PINN on a 1-cm grid
    yy, xx = np.meshgrid(fine, fine, indexing="ij")
    k = len(velocities)
    fig, axes = plt.subplots(1, k, figsize=(2.9 * k, 3.8), squeeze=False, sharex=True, sharey=True)
    for ax, velocity in zip(axes[0], velocities):
        iv = [int(np.argmin(np.abs(solution.v_axis - c))) for c in velocity]
        v = (float(solution.v_axis[iv[0]]), float(solution.v_axis[iv[1]]))
        x = np.stack([xx.ravel(), yy.ravel(), np.full(xx.size, v[0]), np.full(xx.size, v[1])], -1)
        pred = vs.value(torch.as_tensor(x, dtype=torch.float64), t=t).double().cpu().numpy().reshape(yy.shape)
        ax.contour(p, p, ref_t[:, :, iv[0], iv[1]].T, levels=[0.0], colors="k", linewidths=1.4)
        ax.contour(fine, fine, pred, levels=[0.0], colors="r", linestyles="--", linewidths=1.4)
        _collision_disk(ax, vs.collision_radius)
        ax.set_title(rf"$v_{{rel}}$ = ({v[0]:.3g}, {v[1]:.3g}) m/s", fontsize=10)
        ax.set_xlim(-VS_GRID_HALF_WIDTH, VS_GRID_HALF_WIDTH)
        ax.set_ylim(-VS_GRID_HALF_WIDTH, VS_GRID_HALF_WIDTH)
        ax.set_aspect("equal")
        ax.set_xlabel(r"$p_x$ relative (m)")
        ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(4, symmetric=True))
        ax.yaxis.set_major_locator(matplotlib.ticker.MaxNLocator(4, symmetric=True))
        ax.tick_params(axis="x", labelsize=8)   # neighbouring panels' end labels must not meet
    axes[0][0].set_ylabel(r"$p_y$ relative (m)")
    handles = [Line2D([], [], color="k", lw=1.4, label="grid reference (hj_reachability)"),
               Line2D([], [], color="r", ls="--", lw=1.4, label="trained PINN $V_s$"),
               Line2D([], [], color="m", lw=1.0, label=rf"collision disk $\|p\| = r$ = {vs.collision_radius:g} m")]
    fig.tight_layout(w_pad=1.5, rect=(0, 0.1, 1, 0.93))
    fig.suptitle(f"$V_s = 0$ at t = {t:g} s: grid vs PINN (unsafe inside each curve)", fontsize=10)
    fig.legend(handles=handles, loc="lower center", ncol=3, frameon=False, fontsize=9, bbox_to_anchor=(0.5, 0.0))
    return fig

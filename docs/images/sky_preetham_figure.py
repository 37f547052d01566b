"""Writes docs/images/sky_preetham.png (run from the repository root: PYTHONPATH=. python3 docs/images/sky_preetham_figure.py)."""
import numpy as np, matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
from envcap.core.color import luminance
from envcap.sky.preetham import PreethamSky
from envcap.core.latlong import latlong_directions, direction_to_latlong_xy
h, w = 128, 256
d = latlong_directions(h, w)
cases = [(3, 5), (3, 20), (3, 45), (3, 80), (2, 20), (8, 20)]
fig, axes = plt.subplots(3, 2, figsize=(10, 8.2))
for ax, (T, e) in zip(axes.ravel(), cases):
    sky = PreethamSky(T, e, 120)
    L = sky.radiance(d)
    y = luminance(L)
    key = 0.18 / np.exp(np.mean(np.log(y[d[..., 1] > 0] + 1e-6)))  # Reinhard key on the upper dome
    x = L * key
    img = x / (1 + luminance(x))[..., None]
    img = np.where(img <= 0.0031308, 12.92 * img, 1.055 * np.clip(img, 0, None) ** (1 / 2.4) - 0.055)
    ax.imshow(np.clip(img, 0, 1), extent=(0.5, -0.5, -90, 90), aspect="auto")  # lon: +180 left .. -180 right
    sx, sy = direction_to_latlong_xy(sky.sun.direction, h, w)
    ax.plot(0.5 - (sx + 0.5) / w, 90 - (sy + 0.5) / h * 180, "o", mfc="none", mec="r", ms=8)
    E = luminance(sky.sun.illuminance)
    ax.set_title(f"T={T}, sun elev {e} deg, az 120 | zenith {sky.zenith[0]/1e3:.1f} kcd/m2, E_sun {E/1e3:.0f} klx", fontsize=8)
    ax.set_xticks([0.5, 0.25, 0, -0.25, -0.5], ["+180 (-Z)", "+90 (+X)", "0 (+Z)", "-90 (-X)", "-180"], fontsize=7)
    ax.set_yticks([-90, 0, 90]); ax.tick_params(labelsize=7)
    ax.axhline(0, color="w", lw=0.3)
fig.suptitle("Preetham sky, lat-long (OpenEXR convention), per-panel Reinhard; red circle = analytic sun (not drawn in the dome)", fontsize=9)
fig.tight_layout()
fig.savefig("docs/images/sky_preetham.png", dpi=90)

"""
A reduced beam coupled to a spring after reduction
==================================================

A clamped steel beam is reduced for its tip response (``TIP:y``) with the middle cross-section
(``MID:y``) as a second input; afterwards a stiff spring from the middle to the ground is added through
the reduced input matrix. ``krylov`` (moment matching) keeps its accuracy in the coupled system,
``fw-sobt`` (frequency-limited balanced truncation) does not: its error bound holds for the body alone.
This runs ``examples/coupled_beam.py`` at its default size (40 elements, 480 DOF); the examples page
shows it on a 2,700-DOF beam and on a CalculiX beam as well.
"""

import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

try:
    HERE = Path(__file__).resolve().parent
except NameError:  # run cell by cell
    HERE = Path.cwd()
sys.path.insert(0, str(HERE.parents[1] / "examples"))

import coupled_beam  # noqa: E402

result = coupled_beam.run(40, 8)
print(f"clamped beam, {result['n_dof']} DOF, order {result['order']}, "
      f"spring {result['spring_N_per_m']:.3g} N/m at mid-length")
print(f"{'method':8s} {'band_error':>11s} {'with spring':>12s} {'max_rel_error':>14s} {'with spring':>12s}")
for name, row in result["methods"].items():
    print(f"{name:8s} {row['band_error']:11.2e} {row['band_error_coupled']:12.2e} "
          f"{row['max_rel_error']:14.2e} {row['max_rel_error_coupled']:12.2e}")

# %%
# The relative error over frequency, alone (solid) and with the spring (dashed), as the example draws it:

with tempfile.TemporaryDirectory() as folder:
    figure = Path(folder) / "coupled_beam.png"
    coupled_beam.plot(result, figure)
    image = plt.imread(figure)
fig, ax = plt.subplots(figsize=(image.shape[1] / 120, image.shape[0] / 120), dpi=120)
ax.imshow(image)
ax.set_axis_off()
fig.subplots_adjust(0, 0, 1, 1)

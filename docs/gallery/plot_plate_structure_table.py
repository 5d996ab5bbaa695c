"""
Four reductions of a plate-and-rods structure
=============================================

The built-in plate-and-rods structure (an upper plate with a central hole on four rods, the lower plate
clamped) is excited and measured at the wall of the hole through an RBE3 coupling: six inputs and six
collocated outputs, Rayleigh damping with the ratio 0.01 at both ends of the band 1-2000 Hz. ``krylov``,
``two-step``, ``pod`` and ``modal`` are judged on one full FRF beside the band errors of the reference
comparison. This runs ``examples/plate_structure_table.py`` at the resolution ``n=12`` (the script's
default ``n=56`` gives 35,988 DOF).
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

import plate_structure_table  # noqa: E402

result = plate_structure_table.run(12)
print(plate_structure_table.table(result))

# %%
# The relative error over frequency of the four bodies (grey lines: the full model's resonances):

with tempfile.TemporaryDirectory() as folder:
    figure = Path(folder) / "plate_structure_table.png"
    plate_structure_table.plot(result, figure)
    image = plt.imread(figure)
fig, ax = plt.subplots(figsize=(image.shape[1] / 120, image.shape[0] / 120), dpi=120)
ax.imshow(image)
ax.set_axis_off()
fig.subplots_adjust(0, 0, 1, 1)

"""The kernel's state as named structures: named tuples of arrays, which numba passes to its
compiled functions as plain structs (fields resolved at compile time). Taking an array out of
one costs a reference count, paid per call: the functions called many times per step that do
(contact.evaluate_contact and its _footprint, erosion._slide) are inlined into their
callers (``inline="always"``), where numba prunes those counts; measured, the kernel is then
as fast as with its arrays passed one by one (benchmarks/bench_simulator.py).

* :class:`Ground`: the DEM's node grids (nx, ny) [m, Pa, Pa/m]: ``h0`` reference level, ``sp``
  plastic sinkage, ``sy`` yield stress, ``ke`` unloading stiffness, ``js`` accumulated shear
  displacement, ``hl`` loose soil deposited on top.
* :class:`Columns`: the window's columns under the wheel (one entry per column k, x from the
  axle): ``xi`` x [m], ``e`` the wheel's lowest point above the axle level [m], ``eb`` the tip
  circle's, ``gtop`` the highest ground level, ``fx``/``fz`` the surface normal, ``gx`` the
  border taper along x, ``gyc`` its cumulative sum across the width (nyw + 1).
* :class:`Patches`: runs of nodes of one column with the same state (contact.build_patches):
  ``pc`` column, ``pj0``/``pj1`` row range, ``pst`` state (h0, sp, sy, ke, js), ``pflag`` 0 free,
  1 elastic, 2 yielding, ``psig`` stress [Pa].
* :class:`Marks`: per window column + 2 and row: ``cflag`` what the wheel did to the node this
  step, ``dsp`` the plastic sinkage it added [m].
* :class:`Window`: this step's window: first column ``c0``, columns ``ncw``, first row under the
  wheel ``jw0``, rows under the wheel ``nyw``.
* :class:`FlowScratch`: the flow fields' scratch rows (``work`` float, ``iwork`` int) and
  erosion's work list (``queue``, ``inq``).
"""

from __future__ import annotations

from collections import namedtuple

__all__ = ["Columns", "FlowScratch", "Ground", "Marks", "Patches", "Window"]

Ground = namedtuple("Ground", ["h0", "sp", "sy", "ke", "js", "hl"])
Columns = namedtuple("Columns", ["xi", "e", "eb", "gtop", "fx", "fz", "gx", "gyc"])
Patches = namedtuple("Patches", ["pc", "pj0", "pj1", "pst", "pflag", "psig"])
Marks = namedtuple("Marks", ["cflag", "dsp"])
Window = namedtuple("Window", ["c0", "ncw", "jw0", "nyw"])
FlowScratch = namedtuple("FlowScratch", ["work", "iwork", "queue", "inq"])

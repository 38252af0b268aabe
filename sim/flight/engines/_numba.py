"""The fast engine: one numba kernel that runs drones in SIMD lanes.

The kernel computes what :func:`sim.flight.engines._numpy.numpy_step` computes (same
controller, same mixer and saturation, same semi-implicit Euler step, same divergence
rules). Drones are independent within a chunk (the disturbances depend on time only),
so the work is laid out for the vector units:

* ``prange`` over *blocks* of ``LANES`` drones (the two cores share the blocks);
* per block, a serial loop over the chunk's steps, and inside it one loop over the
  block's lanes that LLVM vectorises (AVX2/AVX-512: 4/8 drones per instruction, the
  rest by unrolling). The loop body has no calls and no data-dependent branches: every
  ``if`` of the numpy step is a select (the saturation, the limiter, the anti-windup,
  ``sig`` at 0, the divergence masks), and the transcendental functions are the plain
  arithmetic of :mod:`sim.flight.engines._vmath` (libm calls would stop the vectoriser;
  the pip llvmlite has no SVML). The lane loop's trip count is a runtime value (a
  small constant one is fully unrolled before the vectoriser sees it); with AVX-512 it
  compiles to 8-wide zmm arithmetic. ``benchmarks/bench_sim.py``
  (``test_kernel_lane_loop_is_vectorised``, slow: it compiles the kernel afresh) fails if
  its machine code stops using packed arithmetic; ``tests/test_flight_vmath.py`` checks
  the same for the functions in a loop of the kernel's pattern.
* The block's state lives in one scratch array laid out *structure of arrays*, field
  by field with the block's drones contiguous (``sc[field * LANES + lane]``). That
  bends the project's drones-on-the-first-axis rule *inside* the kernel only: a vector
  load needs the same field of consecutive drones next to each other, and one array
  with compile-time offsets lets LLVM prove that no two fields alias. The kernel's
  inputs and outputs keep the ``(N, ...)`` layout; the scratch is filled and written
  back once per chunk.
* What depends on a drone's data but not on its arithmetic stays scalar and outside
  the lane loop: finding each drone's polynomial piece (a cursor that only moves
  forward with time; the piece's coefficients are copied into the scratch when it
  changes; most steps skip even the per-lane test, see :func:`_block_window`), the GNSS
  table rows at an epoch, the wind table rows when the 10 Hz wind
  grid advances, the frames and telemetry rows. The reference is evaluated by one
  helper, :func:`_ref_at`, at the true time (the flown error is measured against it)
  and at the drone's own clock (what the controller flies when a clock offset is on).

The wind of the quadratic drag acts at each drone's *flown* position: it is interpolated
from tables of the wind and its spatial Jacobian sampled at the *planned* position, plus
the first-order term of the flown-minus-planned displacement, clamped
(:mod:`sim.flight.engines._tables`); the exact field would need the turbulence modes'
cosines per drone-step inside the kernel.

``cache=True`` keeps the compiled kernel on disk (``__pycache__``), so only the first
run on a machine pays the compile time (about 6 min of CPU and 2.6 GiB: see "Compile cost" below).

What bounds the lane step (issue 20): neither its flops nor its memory traffic, but its
dependency chains in the out-of-order window. llvm-mca (LLVM 14's Ice Lake model, its nearest
AVX-512 model to Zen 4) on the step's machine code (8 drones, ~2,160 instructions): 1,610
cycles for one step against 540 cycles of port throughput; the longest dependency chain
through the step is ~640 cycles (the reference, ``sig``'s ``exp(h log)``, the limiter's and
the attitude resolution's square roots and divisions, asin, the attitude law, the mixer, the
integration), and a 320-entry reorder buffer holds too little of the step to run the rest
beside it. Measured: ~1,700 cycles per step on Zen 4 (18.7 M drone-steps per CPU second at
~4 GHz). So a shorter chain pays (Estrin polynomials in ``_vmath``: 1.02-1.035x), and more
independent work per instruction window would (two blocks' chains interleaved) but spills
(measured below: 0.75-0.92x). Square roots and divisions
share one divider unit that is not pipelined like the FMA units, so they were cut where an
exact rewrite exists (``sig`` as ``exp(h log(x·x))``, atan2's sector by products, the
mixer's torque shares by hoisted reciprocals: 23 divisions + 17 square roots per
drone-step down to 14 + 9, ~1.1x). Tried and measured slower on this machine, so not
kept: splitting the step into five stage loops over the lanes (loop fission: 0.7x, more
scratch traffic; and with each stage looping over 32 or 64 lanes, so that a stage has 4-8
independent vectors for the window: 0.84x and 0.81x of the fused kernel, as at 16 lanes, 0.83x:
alternating single-thread rounds in one process, kfast-fission c2f3d56 against its parent, so
the fission does not lose for want of independent work), a Newton-iteration reciprocal
square root instead of the divider (0.6x), 32 lanes per block (0.75x; sixteen to eight: 1.08x,
kept) and LLVM's forced vector interleaving (0.8x, register spills); AVX2 code for the
same Zen 4 (``NUMBA_CPU_NAME=znver3``, two ymm halves per block): no faster per CPU second
(15.5-18.3 against 17.9-19.1 M drone-steps/s in four alternating process pairs).

Memory operations are a third of the lane loop (its machine code at 16 lanes, per 8
drone-steps: 2,077 instructions, of which ~1,030 arithmetic, 292 loads/stores of the scratch,
590 stack accesses: 214 spill stores, 270 reloads of them and 106 reads of 87 spilled loop
invariants (the gains and the step's uniform inputs), 156 register moves). On Zen 4 a zmm
load or store occupies its port twice as long as a ymm one. numba aligns arrays to 32
bytes only, so in about half of the processes every 8-wide field access of the scratch
straddled two cache lines; the scratch now starts on a 64-byte line (``_aligned_zeros``).
Measured (alternating single-thread rounds inside one process, median of 6): with 16 lanes
1.12x main's kernel in a process where its scratch was misaligned, and a copy forced 32
bytes off the line ran at 1.02x of it; with the 8 lanes kept now, 1.045x main's kernel
(range 1.02-1.10), but the copy forced off the line also ran at 1.04x, so at 8 lanes (the
block's scratch stays in the L1 cache) the line splits cost little and the gain is not
the alignment itself (code placement, or the scratch as a view; not resolved).
Tried and measured no faster, so not kept: double-buffering the step's state (read the
step from one copy of the 68 state, controller and statistics fields, write each candidate
unconditionally to the other as soon as it is final, alternate per step with the two
offsets as constants in two copies of the lane loop, restore the lanes that do not commit
in a scalar pass): it removes the end-of-step selects and cuts the spills (spill stores
214 -> 164, their reloads 270 -> 228, 2,077 -> ~1,990 instructions per copy) but measured
0.99x (16 lanes, both aligned; median of 6 alternating rounds in one process, range 0.97-1.03, an
A/A pair in the same run 0.97-1.04), the cost of the second loop copy and the fix-up pass
eating the saving. Also measured and not kept: skipping the telemetry stores when no
telemetry is asked for (a kernel specialisation for ``tel=None``): 1.038x, but the machine
code of the two specialisations contracts multiply-adds differently (a product that is also
stored is not fused), so a flight with telemetry would differ from the same flight without
it in the last bits, and the closed loop amplifies that (see below); moving the
attitude's state-only part (sin/cos, W, its ``sig`` factors) ahead of the position law in
the source, so that it could fill the window while the position chain waits: 0.97x (LLVM's
scheduler reorders the block anyway).

Multi-rate (``IsmcGains.position_rate_hz``, default 250 Hz): the outer loop (the controller's
reference, the position law with its ``sig`` = exp(h log), the limiter, the attitude resolution's
square root, division, asin and atan2, their integrators) runs at steps k = 0 mod K only, its
outputs held in the controller state in between (the command filter's input ramps between two
runs' Θ_ref); the command filter, the attitude law, the allocation, the estimator and the plant
run every 1 ms step, so a drone-step is still a full step of rigid-body flight with every error
model. The condition is uniform over the lanes, so it sits outside the lane loop: the step loop
has two lane loops, each the body :func:`_lane_step` inlined with ``outer`` a constant (True or
False), both branch-free and vectorised (two bodies to compile: see "Compile cost").
Measured first (a throwaway copy of this kernel with the outer loop removed, alternating
single-thread rounds in one process, kernel CPU time, 4,000 drones, gusty-rtk): the lane step
without the outer loop ran at 1.74x the full step (range 1.73-1.75 over 6 rounds), so the outer
loop is ~43 % of the step. As built (``benchmarks/bench_precision.py -k float32_against``, 6
rounds): 250 Hz 1.44x the kernel with every loop at 1 kHz (1.43-1.46); the float32 kernel at
250 Hz 1.76x the float64 1 kHz one (in an earlier run of the same rounds, 100 Hz: 1.47x, 1.99x).

Compile cost (a cold cache; ``python -m benchmarks.kernel_compile_cost float64 float32``: a child
process compiling the kernel's specialisation on an empty ``NUMBA_CACHE_DIR``, its CPU time and peak
RSS; measured with the machine shared by other compiles, load ~10 on its 2 cores): float64 351 s of
CPU, 2,659 MiB; float32 360 s, 2,634 MiB. Where it goes (wall time of numba's passes in the same
runs, float64/float32): numba's parfor *fusion* pass over the kernel 50/56 %, the parfor pre-lowering
and lowering of the kernel and its gufunc 26/18 %, numba inlining the two lane steps 9/12 %, and LLVM
itself only 4/2 % (time under numba's LLVM lock): the cost is numba's Python passes, not LLVM.
Tried and measured (the same session; speed by ``python -m benchmarks.kernel_ab``, alternating
single-thread rounds in one process against a copy of main's module, 4,000 drones, gusty-rtk, 6
rounds), not kept:

* each lane loop an ``njit(cache=True)`` function of its own (the kernel's fastmath flags and error
  model), called from the step loop once per block-step: 81 s and 1,670 MiB (float64), 77 s and
  1,689 MiB (float32), i.e. 4.3-4.7x less CPU, results bit-identical to main's (positions, final
  states, statistics, telemetry; a process that compiled matched one that loaded; the engine and
  multi-rate tests passed), but the kernel ran at 0.80x (float64, 0.803-0.809) and 0.74x (float32,
  0.737-0.745) of main's; 0.73x (0.65-0.81) and 0.91x (0.85-0.93) in a later session at load 6-10
  (branch splitfast, 4833f15). Why, from the cached object code (``objdump``): LLVM vectorises a
  lane function only at its *second* optimisation, when numba links its IR into the kernel's module
  (the function's own library is scalar: 859 scalar-double operations, no packed ones), and it stays
  a function called per block-step whose every call runs a prologue of 586 (outer loop) / 438 (held)
  instructions before its vector pass of 2,157 / 1,350: 151 broadcasts of the scalar constants and
  step inputs to zmm, 154 zmm stores spilling them, 70 argument loads, 85 constant-pool addresses,
  ~30 % more instructions per step at 250 Hz (in this kernel that work sits outside the step loop).
  Tried on the split, not kept: ``njit(forceinline=True)`` (61 s, but LLVM inlines at its first, O0
  pass and the kernel's lane loops come out scalar); a second ``forceinline`` level so the wrapper's
  library vectorises first (only the held loop vectorised, 339 s); the constants and step inputs
  through two small arrays instead of ~75 scalar arguments (0.97x the split, bit-identical: the
  argument passing is not the cost); the constants as 49 per-lane scratch fields (0.98x, not
  bit-identical). Untried: a block's whole step loop in one function per outer-loop phase, or
  vectorising the lane function in its own library so that ``forceinline`` carries vector code;
* the whole ``prange`` body (the step loop with both lane loops) an ``njit`` function of its own,
  called once per block and chunk, so that the parfor passes see one call: still compiling after 337 s
  of CPU (float64) and 331 s (float32), against main's 351 s and 360 s (stopped there). So taking
  the body out of the parfor passes does not cut it: the cost follows the size of the one function
  that holds both lane steps, whichever pass spends it (the split above, one lane step per function,
  is what cut it).

Single precision: :mod:`sim.flight.engines._numba_f32` is this step with the control laws in
float32 (``precision="float32"``, opt-in): 1.30-1.41x this kernel, within 1 mm of its flights,
without the 1e-9 agreement with the reference (measurements and the per-quantity choice there).

The numpy step is the readable reference; ``tests/test_flight_engines.py`` checks that
both agree to 1e-9 over one simulated second (24 drones off their circles, with and
without disturbances), from arbitrary states for a few steps, and with the error models
on.

Floating point: ``fastmath`` allows reassociation, FMA contraction, approximate
functions and signed-zero freedom, but *not* ``nnan``/``ninf`` (the divergence checks
need NaN and inf to behave) nor ``arcp`` (reciprocal instead of division: it changes the
mixer's rounding so that the hover thrust no longer comes back as exactly m·g, and hover
would drift by ~1e-7 m in a second). The elementary functions of ``_vmath`` are compiled
separately with FMA contraction only (reassociation would undo their exact argument
reductions) and inlined by LLVM with their own flags. The kernel holds hover
bit-exactly, like the reference (``sin 0 = 0``, ``cos 0 = 1``, ``asin 0 = atan2(0, u_z) = 0``
exactly), and otherwise differs from it by rounding: ``_vmath``'s functions here (within
4 ulp of numpy's, tested), numpy's own there, FMA contraction and reassociation here.
That is invisible while errors are above the discrete chattering floor of the
finite-time laws, but once an error sits at that floor (``sig(e, 1/2)`` has unbounded
gain at 0, so the sampled loop chatters at about 1e-9 rad/s) the closed loop amplifies
an ulp by ~7 % per step: from there the two engines give equally valid trajectories
that drift apart at the 1e-5 level inside the chatter, with the same tracking
statistics. Two runs of the same engine are bit-identical, and a drone's result does
not depend on the block or lane it runs in (lanes never mix).
"""

from __future__ import annotations

import logging
import math
import os
import pickle
import subprocess
import sys
from typing import Any

import numba as nb
import numpy as np

from sim.flight._disturbance import SHEAR_LINEAR_RADIUS_FRACTION
from sim.flight._quadrotor import YAW_HEADROOM
from sim.flight.engines._state import (
    C_E2_0,
    C_E4_0,
    C_GATE,
    C_IATT,
    C_IERR,
    C_INNOV,
    C_IPOS,
    C_LAST_THRUST,
    C_LIMHOLD,
    C_LIMITED,
    C_PHAT,
    C_PUSHHOLD,
    C_RESET,
    C_RHOLD,
    C_ROTOR,
    C_RPREV,
    C_SAPREV,
    C_SPREV,
    C_THC,
    C_THC_DOT,
    C_UD,
    C_UDA,
    C_UHOLD,
    C_UNORM,
    C_VHAT,
    CTRL_SIZE,
    D_CLOCK,
    D_DRAG,
    D_IX,
    D_IY,
    D_IZ,
    D_MASS,
    D_MOTOR,
    D_SAG_RATE,
    D_SIZE,
    D_THRUST,
    DIVERGED_GROUND,
    DIVERGED_NONFINITE,
    DIVERGED_OVERPOWERED,
    DIVERGED_RUNAWAY,
    LIMITED_ALIGN_COS,
    LIMITED_FRACTION,
    LIMITED_TAU_S,
    STAT_COUNT,
    STAT_DTHRUST,
    STAT_MAX,
    STAT_SUMSQ,
    STATS_SIZE,
    TEL_SIZE,
    ErrorSwitches,
    RefChunk,
    TrackingReference,
)
from sim.flight.engines._tables import WIND_GRAD_SIZE, ChunkTables, ideal_drone_constants
from sim.flight.engines._vmath import vasin, vatan2, vexp, vlog, vsincos

__all__ = ["COMPILE_NOTE", "LANES", "run_chunk_numba"]

#: Logged (``WARNING``, this module's logger, a child of ``sim``) once per process and kernel
#: specialisation before a compile that the disk cache cannot spare: a first run sat silent for
#: minutes otherwise. The CLI prints ``sim``'s warnings on stderr (``app.cli``).
COMPILE_NOTE = "compiling the flight kernel for this machine (first run, a few minutes of CPU; cached afterwards)"
# The compiling child's first statement: its soft data limit up to the hard one (see _cached_machine_code).
_LIFT_DATA_LIMIT = ("import resource; _h = resource.getrlimit(resource.RLIMIT_DATA)[1]; "
                    "resource.setrlimit(resource.RLIMIT_DATA, (_h, _h))")
_COMPILE_TIMEOUT_S = 4 * 3600.0
_log = logging.getLogger(__name__)

#: Drones per block: the lane loop's trip count (one AVX-512 or two AVX2 vectors of float64). Eight,
#: not sixteen: a block's scratch is ~205 fields x LANES x 8 bytes, 26 KB at sixteen lanes, which with
#: the loop's stack spills overfills the 32 KB L1 data cache; at eight (13 KB) it fits. Measured in
#: alternating single-thread A/B rounds (kernel CPU time, 4,000 drones, gusty-rtk): 1.08x the
#: median of sixteen lanes (11 of 15 rounds faster, and a steadier rate), results bit-identical
#: (lanes never mix).
LANES = 8

# ---- scratch layout: field f of lane l at sc[f * LANES + l] ------------------------------
F_STATE = 0  # the 12 plant states (p, v, Θ, Ω)
F_CTRL = 12  # the CTRL_SIZE controller states, in engines._state's order
F_DRONE = F_CTRL + CTRL_SIZE  # the D_SIZE per-drone constants
F_INV = F_DRONE + D_SIZE  # 1/I_x, 1/I_y, 1/I_z, 1/m of the true plant
F_TF, F_TL = F_INV + 4, F_INV + 5  # the drone's first and last break (s)
F_STAT = F_INV + 6  # the STATS_SIZE running statistics
F_ALIVE = F_STAT + STATS_SIZE  # 1.0 while flying
F_DSTEP = F_ALIVE + 1  # divergence step (-1 while flying)
F_REASON = F_ALIVE + 2  # divergence reason code
# A reference cache: the piece's start (s), then per axis the 13 coefficients of
# position c0..c5, velocity d2..d5 (d_k = k c_k) and acceleration 4 d5, 3 d4, 2 d3.
REF_SIZE = 1 + 3 * 13
F_REF = F_ALIVE + 3  # the piece at the true time
F_REFC = F_REF + REF_SIZE  # the piece at the drone's own clock
F_GNSS = F_REFC + REF_SIZE  # GNSS measurement error of the current epoch (m)
F_WA, F_WB = F_GNSS + 3, F_GNSS + 6  # wind at the two grid times around t (m/s)
# Its derivatives over the grid interval: the mean of the two grid times' (1/s; _tables.ChunkTables.wind_grad).
F_WJ = F_GNSS + 9
F_TEL = F_WJ + WIND_GRAD_SIZE  # the TEL_SIZE telemetry values of the last step
F_TELOK = F_TEL + TEL_SIZE  # 1.0 when the last step computed them (the drone flew it)
NF = F_TELOK + 1


@nb.njit(inline="always", cache=True)
def _sig_scale(x0: float, x1: float, x2: float, h: float) -> float:
    """Factor ``||x||^(r-1)`` of ``sig(x, r)`` as ``(x·x)^h``, ``h = (r-1)/2``; 0 at x = 0, as selects.

    One ``exp(h log(x·x))`` serves every exponent: no square root for the norm and no
    separate ``1/sqrt`` path for r = 1/2 (the numpy reference's special cases agree to a
    few ulp; r = 1 gives h = 0 and exactly 1). The divider unit, shared by every division
    and square root, is what the lane loop waits on most, so this saves two square roots and
    a division per call (``sim.flight.control._ismc.sig``).
    """
    q = x0 * x0 + x1 * x1 + x2 * x2
    pos = q > 0.0
    out = vexp(h * vlog(q if pos else 1.0))
    return out if pos else 0.0


@nb.njit(inline="always", cache=True)
def _unit_scale(x0: float, x1: float, x2: float, eps: float) -> float:
    """Factor ``1/max(||x||, eps)``, 0 at x = 0 (``sim.flight.control._ismc.unit``), as a select."""
    n = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    inv = 1.0 / max(n, eps)
    return inv if n > 0.0 else 0.0


@nb.njit(inline="always", cache=True)
def _ismc_law(
    ex: float, ey: float, ez: float, edx: float, edy: float, edz: float, fx: float, fy: float, fz: float,
    ka: float, kb: float, ha: float, hb: float, e0x: float, e0y: float, e0z: float,
    ix: float, iy: float, iz: float, spx: float, spy: float, spz: float, gain: float, eps: float,
    eps_q: float,
) -> tuple[float, ...]:
    """One ISMC law, shared by position (spec 4) and attitude (spec 6); scalar form of ``sim.flight.control._ismc``.

    Args: error e and its rate ė (3 components each), the drift f, gains k_a, k_b of the
    nominal law and its powers as h = (r - 1)/2 (see ``_sig_scale``), ė at the start, the
    integral of the nominal closed loop, the previous step's sliding variable, the switching
    gain and the switching law's boundary layers (on s and on s - s_prev).

    Returns:
        (u_n x, y, z: nominal control; s x, y, z: sliding variable; w x, y, z: rate of u_d).
    """
    sa = _sig_scale(ex, ey, ez, ha)
    sb = _sig_scale(edx, edy, edz, hb)
    unx = -ka * (ex * sa) - kb * (edx * sb) - fx
    uny = -ka * (ey * sa) - kb * (edy * sb) - fy
    unz = -ka * (ez * sa) - kb * (edz * sb) - fz
    sx = edx - e0x - ix
    sy = edy - e0y - iy
    sz = edz - e0z - iz
    us = _unit_scale(sx, sy, sz, eps)
    qx = sx - spx
    qy = sy - spy
    qz = sz - spz
    uq = _unit_scale(qx, qy, qz, eps_q)
    wx = -gain * (sx * us + 0.5 * (qx * uq))
    wy = -gain * (sy * us + 0.5 * (qy * uq))
    wz = -gain * (sz * us + 0.5 * (qz * uq))
    return unx, uny, unz, sx, sy, sz, wx, wy, wz


@nb.njit(inline="always", cache=True)
def _shift(hi_p: float, lo_p: float, hi_m: float, lo_m: float, top: float) -> float:
    """PX4's desaturation gain for a direction with entries ±1, from the extremes of the rotors it moves.

    ``hi_p``/``lo_p``: the largest and smallest rotor of those with entry +1, ``hi_m``/``lo_m`` of
    those with -1 (pass ``hi = -inf, lo = +inf`` where there are none). The generic form (the
    most negative plus the most positive of each out-of-range rotor's multiple,
    ``sim.flight._quadrotor._desaturation_gain``) reduces to these, exactly: an over-range +1
    rotor's multiple ``top - a`` is most negative at the largest, an under-range -1 rotor's ``a``
    at the smallest, and so on; in-range rotors' multiples (0) change nothing. Two levels of
    min/max instead of a select and a four-way tree per rotor (the step is latency-bound).
    """
    k_min = min(min(top - hi_p, lo_m), 0.0)
    k_max = max(max(0.0 - lo_p, hi_m - top), 0.0)
    return k_min + k_max


@nb.njit(inline="always", cache=True)
def _allocate(base: float, roll: float, pitch: float, yw: float, top: float, top_yaw: float,
              on: bool) -> tuple[float, float, float, float, bool, bool]:
    """:func:`sim.flight._quadrotor.allocate` for one drone, as selects.

    Returns ``(ω1², ω2², ω3², ω4², thrust short, torque short)``. PX4's sequential
    desaturation (airmode for roll and pitch; ``on`` False: the plain clip) from the rotors'
    extremes (``_shift``): a shift along a ±1 direction moves each extreme by exactly the
    shift (rounding is monotonic), so the second, half pass needs no new extremes. Equal to the
    numpy version's results (tested).
    """
    a1, a2, a3, a4 = base - pitch, base + roll, base + pitch, base - roll
    ninf, pinf = -math.inf, math.inf
    # The collective, either way (airmode for roll and pitch).
    hi = max(max(a1, a2), max(a3, a4))
    lo = min(min(a1, a2), min(a3, a4))
    g = _shift(hi, lo, ninf, pinf, top)
    g = g if on else 0.0
    g2 = 0.5 * _shift(hi + g, lo + g, ninf, pinf, top)
    g2 = g2 if on else 0.0
    t1 = (g != 0.0) | (g2 != 0.0)
    a1, a2, a3, a4 = (a1 + g) + g2, (a2 + g) + g2, (a3 + g) + g2, (a4 + g) + g2
    # Yaw (+1, -1, +1, -1), with room above the top.
    a1, a2, a3, a4 = a1 + yw, a2 - yw, a3 + yw, a4 - yw
    hp, lp = max(a1, a3), min(a1, a3)
    hm, lm = max(a2, a4), min(a2, a4)
    g = _shift(hp, lp, hm, lm, top_yaw)
    g = g if on else 0.0
    g2 = 0.5 * _shift(hp + g, lp + g, hm - g, lm - g, top_yaw)
    g2 = g2 if on else 0.0
    y = (g != 0.0) | (g2 != 0.0)
    a1, a2, a3, a4 = (a1 + g) + g2, (a2 - g) - g2, (a3 + g) + g2, (a4 - g) - g2
    # The collective again, lowered only.
    hi = max(max(a1, a2), max(a3, a4))
    lo = min(min(a1, a2), min(a3, a4))
    g = _shift(hi, lo, ninf, pinf, top)
    use = (g <= 0.0) & on
    g = g if use else 0.0
    g2 = 0.5 * _shift(hi + g, lo + g, ninf, pinf, top)
    g2 = g2 if use else 0.0
    t2 = (g != 0.0) | (g2 != 0.0)
    a1, a2, a3, a4 = (a1 + g) + g2, (a2 + g) + g2, (a3 + g) + g2, (a4 + g) + g2
    hi = (hi + g) + g2
    lo = (lo + g) + g2
    cut = (lo < 0.0) | (hi > top)
    o1 = min(max(a1, 0.0), top)
    o2 = min(max(a2, 0.0), top)
    o3 = min(max(a3, 0.0), top)
    o4 = min(max(a4, 0.0), top)
    return o1, o2, o3, o4, (t1 | t2) | cut, y | cut


@nb.njit(inline="always", cache=True)
def _axis_at(sc: np.ndarray, o: int, u: float, inside: bool) -> tuple[float, float, float]:
    """Position, velocity, acceleration of one axis of a cached piece (13 fields from ``o``) at u."""
    c0, c1, c2, c3 = sc[o], sc[o + LANES], sc[o + 2 * LANES], sc[o + 3 * LANES]
    c4, c5 = sc[o + 4 * LANES], sc[o + 5 * LANES]
    d2, d3, d4, d5 = sc[o + 6 * LANES], sc[o + 7 * LANES], sc[o + 8 * LANES], sc[o + 9 * LANES]
    a3, a2, a1 = sc[o + 10 * LANES], sc[o + 11 * LANES], sc[o + 12 * LANES]
    pos = ((((c5 * u + c4) * u + c3) * u + c2) * u + c1) * u + c0
    vel = (((d5 * u + d4) * u + d3) * u + d2) * u + c1
    acc = ((a3 * u + a2) * u + a1) * u + d2
    return pos, (vel if inside else 0.0), (acc if inside else 0.0)


@nb.njit(inline="always", cache=True)
def _ref_at(sc: np.ndarray, base: int, lane: int, t: float, tf: float, tl: float) -> tuple[float, ...]:
    """The reference from the lane's cached piece at ``base`` at time t: (p x, y, z, v x, y, z, a x, y, z).

    ``Trajectories.evaluate`` by Horner's rule: clamped to the drone's show ``[tf, tl]``,
    at rest outside it. The derivative coefficients were formed as
    ``Trajectories.evaluate`` forms them (k·c_k, then (k-1)·(k·c_k)), so both engines
    round alike. The one evaluation for the true time and the drone's own clock.
    """
    inside = (t >= tf) & (t <= tl)
    u = min(max(t, tf), tl) - sc[base * LANES + lane]
    px, vx, ax = _axis_at(sc, (base + 1) * LANES + lane, u, inside)
    py, vy, ay = _axis_at(sc, (base + 14) * LANES + lane, u, inside)
    pz, vz, az = _axis_at(sc, (base + 27) * LANES + lane, u, inside)
    return px, py, pz, vx, vy, vz, ax, ay, az


@nb.njit(inline="always", cache=True)
def _aligned_zeros(size: int) -> np.ndarray:
    """``np.zeros(size)`` starting on a 64-byte cache line (a view into a slightly longer array).

    numba aligns arrays to 32 bytes only; a scratch that starts half-way into a line makes every
    8-wide (zmm) load and store of a field straddle two lines, and which of the two a process
    gets depends on where its allocator happens to place the array (see the module docstring).
    """
    buf = np.zeros(size + 8)
    a0 = (-(buf.ctypes.data // 8)) % 8
    return buf[a0:a0 + size]


@nb.njit(inline="always", cache=True)
def _commit(sc: np.ndarray, field: int, lane: int, value: float, ok: bool) -> None:
    """Store ``value`` into the lane's field when ``ok`` (a select: the store itself is unconditional)."""
    idx = field * LANES + lane
    sc[idx] = value if ok else sc[idx]


@nb.njit(inline="always", cache=True)
def _load_piece(sc: np.ndarray, base: int, lane: int, coeffs: np.ndarray, breaks: np.ndarray, i: int,
                p: int) -> None:
    """Copy drone i's piece p into the lane's reference cache at ``base`` (see ``_ref_at``)."""
    sc[base * LANES + lane] = breaks[i, p]
    for a in range(3):
        o = (base + 1 + 13 * a) * LANES + lane
        for c in range(6):
            sc[o + c * LANES] = coeffs[i, p, a, c]
        d5, d4, d3, d2 = 5.0 * coeffs[i, p, a, 5], 4.0 * coeffs[i, p, a, 4], 3.0 * coeffs[i, p, a, 3], \
            2.0 * coeffs[i, p, a, 2]
        sc[o + 6 * LANES], sc[o + 7 * LANES], sc[o + 8 * LANES], sc[o + 9 * LANES] = d2, d3, d4, d5
        sc[o + 10 * LANES], sc[o + 11 * LANES], sc[o + 12 * LANES] = 4.0 * d5, 3.0 * d4, 2.0 * d3


@nb.njit(inline="always", cache=True)
def _seek(sc: np.ndarray, base: int, lane: int, cur: np.ndarray, nxt: np.ndarray, prv: np.ndarray,
          coeffs: np.ndarray, breaks: np.ndarray, i: int, tc: float, last_piece: int) -> None:
    """Move the lane's piece cursor to the piece holding ``tc`` (the later one at a break), if it left it.

    A cursor only moves forward with time, so this costs two comparisons per step; it
    moves backwards only if the chunk's starting search (done in a row-offset key space)
    rounded past a break.
    """
    if tc >= nxt[lane] or tc < prv[lane]:
        c = cur[lane]
        while c < last_piece and breaks[i, c + 1] <= tc:
            c += 1
        while c > 0 and breaks[i, c] > tc:
            c -= 1
        cur[lane] = c
        nxt[lane] = breaks[i, c + 1] if c < last_piece else math.inf
        prv[lane] = breaks[i, c] if c > 0 else -math.inf
        _load_piece(sc, base, lane, coeffs, breaks, i, c)


@nb.njit(inline="always", cache=True)
def _block_window(sc: np.ndarray, nxt: np.ndarray, prv: np.ndarray, nxtc: np.ndarray, prvc: np.ndarray,
                  use_clock: bool) -> tuple[float, float]:
    """A window ``[lo, hi)`` of times t in which no lane's cursor (true time or own clock) has to move.

    A lane keeps its piece while ``prv <= clamp(t, t_first, t_last) < nxt``; that holds when
    ``prv <= t < nxt`` (the clamp's bounds are the first and last breaks, which never cut a
    piece short, unless the first piece has zero length: then there is no window), and for
    the drone's own clock when ``prv - δ <= t < nxt - δ``. The clock's bounds are moved
    inward by a relative 1e-12 so that rounding of ``t + δ`` can only make the window
    smaller: inside it the per-lane test would find nothing to do, so skipping it leaves every
    result bit-identical.
    """
    lo, hi = -math.inf, math.inf
    for lane in range(LANES):
        tf = sc[F_TF * LANES + lane]
        if not (tf < nxt[lane] and tf < nxtc[lane]):  # a zero-length first piece: no window
            return math.inf, -math.inf
        lo = max(lo, prv[lane])
        hi = min(hi, nxt[lane])
        if use_clock:
            d = sc[(F_DRONE + D_CLOCK) * LANES + lane]
            a, b = prvc[lane] - d, nxtc[lane] - d
            lo = max(lo, a + 1e-12 * (abs(a) + 1.0))
            hi = min(hi, b - 1e-12 * (abs(b) + 1.0))
    return lo, hi


@nb.njit(inline="always", cache=True)
def _lane_step(sc: np.ndarray, lane: int, outer: bool, epoch: bool, cst: tuple[float, ...],
               flg: tuple[bool, ...], stp: tuple[float, ...]) -> None:
    """One control + integration step of one lane (the kernel's vector part), in place in the scratch.

    ``outer`` (a constant at each call: the kernel has one lane loop with True, one with False, the
    branch outside the loops, so each loop's body is branch-free and vectorises) runs the outer
    loop: the controller's reference, the position law, the limiter, the attitude resolution and
    their integrators (``IsmcGains.position_rate_hz``); without it their outputs held in the
    controller state are used (zero-order hold). ``cst``: the kernel's constants, ``flg``: its
    switches, ``stp``: the step's uniform inputs (see ``_kernel``). Inlined (numba IR), so the
    tuples cost nothing.
    """
    L = LANES
    (m, ix, iy, iz, g, arm, kf, km, pg, wmax2, k1, k2, h1, h2, alpha, k3, k4, h3, h4, beta_g, wn, zeta,
     eps_p, eps_pq, eps_a, eps_aq, ki, ilim, izone, uz_min, tan_tilt, wmax2_yaw, inv_ix, inv_iy, inv_iz,
     inv_2akf, inv_4km, limit, ground_z, reset_v, dt, dto, drag, wrad, est_kp, est_kv, gate_h, gate_v,
     gate_n) = cst
    desat, use_clock, use_gnss, use_motor, use_drag = flg
    (t, off0, off1, off2, off3, off4, off5, off6, off7, off8, rps, ysin, ycos, dx0, dx1, dx2, dw0, dw1, dw2,
     d2x, d2y, d2z, kf_step, t_batt, fw, wgt) = stp
    px, py, pz = sc[0 * L + lane], sc[1 * L + lane], sc[2 * L + lane]
    vx, vy, vz = sc[3 * L + lane], sc[4 * L + lane], sc[5 * L + lane]
    ph, th, ps = sc[6 * L + lane], sc[7 * L + lane], sc[8 * L + lane]
    wx, wy, wz = sc[9 * L + lane], sc[10 * L + lane], sc[11 * L + lane]
    alive = sc[F_ALIVE * L + lane] > 0.5
    tf, tl = sc[F_TF * L + lane], sc[F_TL * L + lane]

    # The plan at the true time (+ the shared offset): the flown error is measured
    # against it.
    prx, pry, prz, vrx, vry, vrz, arx, ary, arz = _ref_at(sc, F_REF, lane, t, tf, tl)
    prx, pry, prz = prx + off0, pry + off1, prz + off2
    qx, qy, qz = px - prx, py - pry, pz - prz
    err = math.sqrt(qx * qx + qy * qy + qz * qz)
    err_ok = err <= limit  # false for NaN (a non-finite reference) or a runaway drone
    # Through the show's ground (-inf: none); false for NaN, which is caught as non-finite.
    below = pz < ground_z
    err_ok = err_ok & (pz >= ground_z)
    if outer:  # the controller's reference: the outer loop's input
        if use_clock:  # the controller flies its own clock t + δ (the shared offset stays at t)
            prx, pry, prz, vrx, vry, vrz, arx, ary, arz = _ref_at(
                sc, F_REFC, lane, t + sc[(F_DRONE + D_CLOCK) * L + lane], tf, tl)
            prx, pry, prz = prx + off0, pry + off1, prz + off2
        vrx, vry, vrz = vrx + off3, vry + off4, vrz + off5
        arx, ary, arz = arx + off6, ary + off7, arz + off8

    # What the controller sees: the GNSS/accelerometer estimate, or the true state.
    ph0 = sc[(F_CTRL + C_PHAT) * L + lane]
    ph1 = sc[(F_CTRL + C_PHAT + 1) * L + lane]
    ph2 = sc[(F_CTRL + C_PHAT + 2) * L + lane]
    in0 = sc[(F_CTRL + C_INNOV) * L + lane]
    in1 = sc[(F_CTRL + C_INNOV + 1) * L + lane]
    in2 = sc[(F_CTRL + C_INNOV + 2) * L + lane]
    gcount = sc[(F_CTRL + C_GATE) * L + lane]
    rs0 = sc[(F_CTRL + C_RESET) * L + lane]
    rs1 = sc[(F_CTRL + C_RESET + 1) * L + lane]
    rs2 = sc[(F_CTRL + C_RESET + 2) * L + lane]
    if epoch:
        in0 = (px + sc[(F_GNSS + 0) * L + lane]) - ph0
        in1 = (py + sc[(F_GNSS + 1) * L + lane]) - ph1
        in2 = (pz + sc[(F_GNSS + 2) * L + lane]) - ph2
        # Innovation gate (as the numpy step): reject beyond k σ and count; after
        # gate_n consecutive rejections reset p̂ to the fix, the jump to C_RESET.
        inside = (abs(in0) <= gate_h) & (abs(in1) <= gate_h) & (abs(in2) <= gate_v)
        gcount = 0.0 if inside else gcount + 1.0
        reset = gcount >= gate_n
        gcount = 0.0 if reset else gcount
        ph0 = ph0 + in0 if reset else ph0
        ph1 = ph1 + in1 if reset else ph1
        ph2 = ph2 + in2 if reset else ph2
        rs0 = rs0 + in0 if reset else rs0
        rs1 = rs1 + in1 if reset else rs1
        rs2 = rs2 + in2 if reset else rs2
        in0 = in0 if inside else 0.0
        in1 = in1 if inside else 0.0
        in2 = in2 if inside else 0.0
    if use_gnss:
        # The controller sees p̂ less the part of a reset not yet shed (0 without one).
        cpx, cpy, cpz = ph0 - rs0, ph1 - rs1, ph2 - rs2
        rs0 = rs0 - min(max(rs0, -reset_v * dt), reset_v * dt)
        rs1 = rs1 - min(max(rs1, -reset_v * dt), reset_v * dt)
        rs2 = rs2 - min(max(rs2, -reset_v * dt), reset_v * dt)
        cvx = sc[(F_CTRL + C_VHAT) * L + lane]
        cvy = sc[(F_CTRL + C_VHAT + 1) * L + lane]
        cvz = sc[(F_CTRL + C_VHAT + 2) * L + lane]
    else:
        cpx, cpy, cpz, cvx, cvy, cvz = px, py, pz, vx, vy, vz
    if outer:
        e1x, e1y, e1z = cpx - prx, cpy - pry, cpz - prz

        # ---- position ISMC (spec 4)
        ud0 = sc[(F_CTRL + C_UD) * L + lane]
        ud1 = sc[(F_CTRL + C_UD + 1) * L + lane]
        ud2 = sc[(F_CTRL + C_UD + 2) * L + lane]
        ie0 = sc[(F_CTRL + C_IERR) * L + lane]
        ie1 = sc[(F_CTRL + C_IERR + 1) * L + lane]
        ie2 = sc[(F_CTRL + C_IERR + 2) * L + lane]
        e2x, e2y, e2z = cvx - vrx, cvy - vry, cvz - vrz
        fx, fy, fz = -arx, -ary, -arz - g
        unx, uny, unz, sx, sy, sz, wpx, wpy, wpz = _ismc_law(
            e1x, e1y, e1z, e2x, e2y, e2z, fx, fy, fz, k1, k2, h1, h2,
            sc[(F_CTRL + C_E2_0) * L + lane], sc[(F_CTRL + C_E2_0 + 1) * L + lane],
            sc[(F_CTRL + C_E2_0 + 2) * L + lane],
            sc[(F_CTRL + C_IPOS) * L + lane], sc[(F_CTRL + C_IPOS + 1) * L + lane],
            sc[(F_CTRL + C_IPOS + 2) * L + lane],
            sc[(F_CTRL + C_SPREV) * L + lane], sc[(F_CTRL + C_SPREV + 1) * L + lane],
            sc[(F_CTRL + C_SPREV + 2) * L + lane], alpha, eps_p, eps_pq,
        )
        ux = unx + ud0
        uy = uny + ud1
        uz = unz + ud2
        ux = ux - ki * ie0  # the PID baseline's integral (0 for the ISMC)
        uy = uy - ki * ie1
        uz = uz - ki * ie2
        # Thrust floor and tilt limit (inactive in normal tracking; see PositionGains).
        wux, wuy, wuz = ux, uy, uz
        floor_hit = uz < uz_min
        uz = uz_min if floor_hit else uz
        # ||u_xy|| > u_z tan(tilt) compared squared where the bound is >= 0 (the paper's
        # gains have no floor: a negative bound is always hit, as in the reference), and
        # the scale by rsqrt: no square root or division (the divider is the bottleneck).
        hxy2 = ux * ux + uy * uy
        lim_xy = uz * tan_tilt
        hxy = math.sqrt(hxy2)
        tilt_hit = hxy > lim_xy
        tsc = lim_xy / hxy
        ux = ux * tsc if tilt_hit else ux
        uy = uy * tsc if tilt_hit else uy
        limited = floor_hit | tilt_hit
        # While limited, s integrates the nominal law minus what the limiter took away.
        inx = unx + (ux - wux) if limited else unx
        iny = uny + (uy - wuy) if limited else uny
        inz = unz + (uz - wuz) if limited else unz
    else:  # zero-order hold of the outer loop's outputs (unused names: 0, the commits skip them)
        ux = sc[(F_CTRL + C_UHOLD) * L + lane]
        uy = sc[(F_CTRL + C_UHOLD + 1) * L + lane]
        uz = sc[(F_CTRL + C_UHOLD + 2) * L + lane]
        limited = sc[(F_CTRL + C_LIMHOLD) * L + lane] > 0.5
        e1x, e1y, e1z = 0.0, 0.0, 0.0
        fx, fy, fz = 0.0, 0.0, 0.0
        sx, sy, sz = 0.0, 0.0, 0.0
        inx, iny, inz = 0.0, 0.0, 0.0
        wpx, wpy, wpz = 0.0, 0.0, 0.0
        ud0, ud1, ud2 = 0.0, 0.0, 0.0
        ie0, ie1, ie2 = 0.0, 0.0, 0.0

    sph, cph = vsincos(ph)
    sth, cth = vsincos(th)
    sps, cps = vsincos(ps)
    zbx = cph * sth * cps + sph * sps
    zby = cph * sth * sps - sph * cps
    zbz = cph * cth
    thrust_cmd = m * (ux * zbx + uy * zby + uz * zbz)

    # ---- attitude resolution (spec 5) and command filter
    if outer:
        un2 = ux * ux + uy * uy + uz * uz
        un = math.sqrt(un2)
        ratio = (ux * ysin - uy * ycos) / un if un > 0.0 else 0.0
        ratio = min(max(ratio, -1.0), 1.0)
        rph = vasin(ratio)
        rth = vatan2(ux * ycos + uy * ysin, uz)
        rpp = sc[(F_CTRL + C_RHOLD) * L + lane]  # the previous run's, the ramp's start
        rtp = sc[(F_CTRL + C_RHOLD + 1) * L + lane]
    else:
        rph = sc[(F_CTRL + C_RHOLD) * L + lane]
        rth = sc[(F_CTRL + C_RHOLD + 1) * L + lane]
        rpp = sc[(F_CTRL + C_RPREV) * L + lane]
        rtp = sc[(F_CTRL + C_RPREV + 1) * L + lane]
        un = sc[(F_CTRL + C_UNORM) * L + lane]
    cx = sc[(F_CTRL + C_THC) * L + lane]
    cy = sc[(F_CTRL + C_THC + 1) * L + lane]
    cz = sc[(F_CTRL + C_THC + 2) * L + lane]
    cdx = sc[(F_CTRL + C_THC_DOT) * L + lane]
    cdy = sc[(F_CTRL + C_THC_DOT + 1) * L + lane]
    cdz = sc[(F_CTRL + C_THC_DOT + 2) * L + lane]
    # The filter's input ramps from the previous run's Θ_ref to this one's over the K steps (wgt: the
    # part still to come, 0 at K = 1; as the numpy step). Held as a step, the 300 rad/s filter turned
    # each run's jump into torque spikes that saturated the rotors.
    rph_out, rth_out = rph, rth
    rph = rph - wgt * (rph - rpp)
    rth = rth - wgt * (rth - rtp)
    cddx = wn * wn * (rph - cx) - 2.0 * zeta * wn * cdx
    cddy = wn * wn * (rth - cy) - 2.0 * zeta * wn * cdy
    cddz = wn * wn * (rps - cz) - 2.0 * zeta * wn * cdz

    # ---- attitude ISMC (spec 6)
    # One division for every 1/cos θ term (W, Ẇ): divisions dominate the arithmetic.
    icth = 1.0 / cth
    tth = sth * icth
    w01, w02 = sph * tth, cph * tth
    w11, w12 = cph, -sph
    w21, w22 = sph * icth, cph * icth
    edx = wx + w01 * wy + w02 * wz
    edy = w11 * wy + w12 * wz
    edz = w21 * wy + w22 * wz
    e3x, e3y, e3z = ph - cx, th - cy, ps - cz
    e4x, e4y, e4z = edx - cdx, edy - cdy, edz - cdz
    gax = (wy * (wz * iz) - wz * (wy * iy)) * inv_ix
    gay = (wz * (wx * ix) - wx * (wz * iz)) * inv_iy
    gaz = (wx * (wy * iy) - wy * (wx * ix)) * inv_iz
    # Ẇ Ω (see sim.flight._quadrotor.w_dot_omega), with Θ̇ = (edx, edy) for φ̇, θ̇.
    sec2 = icth * icth
    wd0 = (cph * tth * edx + sph * sec2 * edy) * wy + (-sph * tth * edx + cph * sec2 * edy) * wz
    wd1 = -sph * edx * wy - cph * edx * wz
    wd2 = (w22 * edx + sph * sth * sec2 * edy) * wy + (
        -w21 * edx + cph * sth * sec2 * edy
    ) * wz
    fax = -(gax + w01 * gay + w02 * gaz) + wd0 - cddx
    fay = -(w11 * gay + w12 * gaz) + wd1 - cddy
    faz = -(w21 * gay + w22 * gaz) + wd2 - cddz
    unax, unay, unaz, sax, say, saz, wax, way, waz = _ismc_law(
        e3x, e3y, e3z, e4x, e4y, e4z, fax, fay, faz, k3, k4, h3, h4,
        sc[(F_CTRL + C_E4_0) * L + lane], sc[(F_CTRL + C_E4_0 + 1) * L + lane],
        sc[(F_CTRL + C_E4_0 + 2) * L + lane],
        sc[(F_CTRL + C_IATT) * L + lane], sc[(F_CTRL + C_IATT + 1) * L + lane],
        sc[(F_CTRL + C_IATT + 2) * L + lane],
        sc[(F_CTRL + C_SAPREV) * L + lane], sc[(F_CTRL + C_SAPREV + 1) * L + lane],
        sc[(F_CTRL + C_SAPREV + 2) * L + lane], beta_g, eps_a, eps_aq,
    )
    uda0 = sc[(F_CTRL + C_UDA) * L + lane]
    uda1 = sc[(F_CTRL + C_UDA + 1) * L + lane]
    uda2 = sc[(F_CTRL + C_UDA + 2) * L + lane]
    uax = unax + uda0
    uay = unay + uda1
    uaz = unaz + uda2
    # τ = I W⁻¹ u_a
    tcx = ix * (uax - sth * uaz)
    tcy = iy * (cph * uay + sph * cth * uaz)
    tcz = iz * (-sph * uay + cph * cth * uaz)

    # ---- rotors ("+" mixer of sim.flight._quadrotor), allocation, what acts
    # The thrust share is divided, as in the reference mixer: that rounding is what
    # makes the hover thrust come back as exactly m·g (hover is held bit-exactly).
    # The torque shares (0 in hover) multiply by hoisted reciprocals.
    base = thrust_cmd / (4.0 * kf)
    roll = tcx * inv_2akf
    pitch = tcy * inv_2akf
    yw = tcz * inv_4km
    o1, o2, o3, o4, thrust_short, clipped = _allocate(base, roll, pitch, yw, wmax2, wmax2_yaw, desat)
    # Anti-windup flags (as the numpy step): the position loop freezes when the command
    # is limited or not delivered, the attitude loop when its torque is not (``clipped``).
    sat = (limited | thrust_short) | clipped
    # At the authority limit and pushing back (as the numpy step): "overpowered" vs "runaway".
    lf_old = sc[(F_CTRL + C_LIMITED) * L + lane]
    if outer:
        push = (ux * e1x + uy * e1y + uz * e1z) - g * e1z < 0.0
    else:
        push = sc[(F_CTRL + C_PUSHHOLD) * L + lane] > 0.5
    follows = ux * zbx + uy * zby + uz * zbz > LIMITED_ALIGN_COS * un
    held = 1.0 if sat & push & follows else 0.0
    lf_new = lf_old + (dt / LIMITED_TAU_S) * (held - lf_old)
    if use_motor:  # first-order lag of the squared rotor speeds toward the command
        mot = sc[(F_DRONE + D_MOTOR) * L + lane]
        ro1 = sc[(F_CTRL + C_ROTOR) * L + lane]
        ro2 = sc[(F_CTRL + C_ROTOR + 1) * L + lane]
        ro3 = sc[(F_CTRL + C_ROTOR + 2) * L + lane]
        ro4 = sc[(F_CTRL + C_ROTOR + 3) * L + lane]
        o1 = ro1 + mot * (o1 - ro1)
        o2 = ro2 + mot * (o2 - ro2)
        o3 = ro3 + mot * (o3 - ro3)
        o4 = ro4 + mot * (o4 - ro4)
    # Thrust gain of this drone's rotors, falling with its battery (1 when ideal).
    rg = sc[(F_DRONE + D_THRUST) * L + lane] * (1.0 - sc[(F_DRONE + D_SAG_RATE) * L + lane] * t_batt)
    thrust = kf * (o1 + o2 + o3 + o4) * rg
    tqx = arm * kf * (o2 - o4) * rg
    tqy = arm * kf * (o3 - o1) * rg
    tqz = km * (o1 - o2 + o3 - o4) * rg

    # ---- plant, semi-implicit Euler with the inputs held
    pix = sc[(F_DRONE + D_IX) * L + lane]
    piy = sc[(F_DRONE + D_IY) * L + lane]
    piz = sc[(F_DRONE + D_IZ) * L + lane]
    tpm = thrust * sc[(F_INV + 3) * L + lane]
    ax = tpm * zbx + dx0 + drag * (dw0 - vx)
    ay = tpm * zby + dx1 + drag * (dw1 - vy)
    az = tpm * zbz + dx2 + drag * (dw2 - vz)
    if use_drag:  # quadratic drag on the air-relative velocity
        wa0, wa1, wa2 = sc[F_WA * L + lane], sc[(F_WA + 1) * L + lane], sc[(F_WA + 2) * L + lane]
        wb0, wb1, wb2 = sc[F_WB * L + lane], sc[(F_WB + 1) * L + lane], sc[(F_WB + 2) * L + lane]
        # The wind at the flown position: the table's (at the plan, linear on its grid) plus
        # the first-order terms of the displacement q, clamped (_tables.flown_wind).
        dqx, dqy, dqz = min(max(qx, -wrad), wrad), min(max(qy, -wrad), wrad), min(max(qz, -wrad), wrad)
        hz = SHEAR_LINEAR_RADIUS_FRACTION * (pz - qz)  # pz - qz: the planned height at t
        dsz = min(max(qz, -hz), hz)
        oj = F_WJ * L + lane
        jx = (sc[oj] * dqx + sc[oj + L] * dqy + sc[oj + 2 * L] * dqz) + sc[oj + 9 * L] * dsz
        jy = (sc[oj + 3 * L] * dqx + sc[oj + 4 * L] * dqy + sc[oj + 5 * L] * dqz) + sc[oj + 10 * L] * dsz
        jz = sc[oj + 6 * L] * dqx + sc[oj + 7 * L] * dqy + sc[oj + 8 * L] * dqz
        rlx = vx - ((wa0 + fw * (wb0 - wa0)) + jx)
        rly = vy - ((wa1 + fw * (wb1 - wa1)) + jy)
        rlz = vz - ((wa2 + fw * (wb2 - wa2)) + jz)
        dsp = sc[(F_DRONE + D_DRAG) * L + lane] * math.sqrt(rlx * rlx + rly * rly + rlz * rlz)
        ax -= dsp * rlx
        ay -= dsp * rly
        az -= dsp * rlz
    az -= pg
    odx = (tqx - (wy * (wz * piz) - wz * (wy * piy))) * sc[F_INV * L + lane] + (d2x - sth * d2z)
    ody = (tqy - (wz * (wx * pix) - wx * (wz * piz))) * sc[(F_INV + 1) * L + lane] + (
        cph * d2y + sph * cth * d2z)
    odz = (tqz - (wx * (wy * piy) - wy * (wx * pix))) * sc[(F_INV + 2) * L + lane] + (
        -sph * d2y + cph * cth * d2z)
    nvx, nvy, nvz = vx + dt * ax, vy + dt * ay, vz + dt * az
    npx, npy, npz = px + dt * nvx, py + dt * nvy, pz + dt * nvz
    nwx, nwy, nwz = wx + dt * odx, wy + dt * ody, wz + dt * odz
    nph = ph + dt * (nwx + w01 * nwy + w02 * nwz)
    nth = th + dt * (w11 * nwy + w12 * nwz)
    nps = ps + dt * (w21 * nwy + w22 * nwz)
    if use_gnss:  # estimator: accelerometer prediction plus the held innovation
        nvh0 = cvx + dt * (ax + est_kv * in0)
        nvh1 = cvy + dt * (ay + est_kv * in1)
        nvh2 = cvz + dt * (az + est_kv * in2)
        nph0 = ph0 + dt * (nvh0 + est_kp * in0)
        nph1 = ph1 + dt * (nvh1 + est_kp * in1)
        nph2 = ph2 + dt * (nvh2 + est_kp * in2)
    else:
        nvh0, nvh1, nvh2, nph0, nph1, nph2 = nvx, nvy, nvz, npx, npy, npz

    # ---- controller state candidates
    if outer:  # the outer loop's integrators, with its own step K dt
        ipx = sc[(F_CTRL + C_IPOS) * L + lane] + dto * (inx + fx)
        ipy = sc[(F_CTRL + C_IPOS + 1) * L + lane] + dto * (iny + fy)
        ipz = sc[(F_CTRL + C_IPOS + 2) * L + lane] + dto * (inz + fz)
    else:
        ipx, ipy, ipz = 0.0, 0.0, 0.0
    iax = sc[(F_CTRL + C_IATT) * L + lane] + dt * (unax + fax)
    iay = sc[(F_CTRL + C_IATT + 1) * L + lane] + dt * (unay + fay)
    iaz = sc[(F_CTRL + C_IATT + 2) * L + lane] + dt * (unaz + faz)
    ncdx, ncdy, ncdz = cdx + dt * cddx, cdy + dt * cddy, cdz + dt * cddz
    ncx, ncy, ncz = cx + dt * ncdx, cy + dt * ncdy, cz + dt * ncdz
    # Anti-windup (as the numpy step): the position u_d and the PID integral frozen
    # while the command is limited or not delivered, the attitude u_d only while its
    # torque is not.
    if outer:
        nie0 = min(max(ie0 + dto * e1x, -ilim), ilim) if abs(e1x) < izone else ie0
        nie1 = min(max(ie1 + dto * e1y, -ilim), ilim) if abs(e1y) < izone else ie1
        nie2 = min(max(ie2 + dto * e1z, -ilim), ilim) if abs(e1z) < izone else ie2
        nie0 = ie0 if sat else nie0
        nie1 = ie1 if sat else nie1
        nie2 = ie2 if sat else nie2
        udx = ud0 if sat else ud0 + dto * wpx
        udy = ud1 if sat else ud1 + dto * wpy
        udz = ud2 if sat else ud2 + dto * wpz
    else:
        nie0, nie1, nie2 = 0.0, 0.0, 0.0
        udx, udy, udz = 0.0, 0.0, 0.0
    uadx = uda0 if clipped else uda0 + dt * wax
    uady = uda1 if clipped else uda1 + dt * way
    uadz = uda2 if clipped else uda2 + dt * waz

    # Telemetry of this step (copied out at frame steps for the drones that flew it).
    sc[(F_TEL + 0) * L + lane] = qx
    sc[(F_TEL + 1) * L + lane] = qy
    sc[(F_TEL + 2) * L + lane] = qz
    sc[(F_TEL + 3) * L + lane] = e3x
    sc[(F_TEL + 4) * L + lane] = e3y
    sc[(F_TEL + 5) * L + lane] = e3z
    sc[(F_TEL + 6) * L + lane] = ph - rph
    sc[(F_TEL + 7) * L + lane] = th - rth
    sc[(F_TEL + 8) * L + lane] = ps - rps
    sc[(F_TEL + 9) * L + lane] = thrust
    sc[(F_TEL + 10) * L + lane] = tqx
    sc[(F_TEL + 11) * L + lane] = tqy
    sc[(F_TEL + 12) * L + lane] = tqz
    sc[(F_TEL + 13) * L + lane] = 1.0 if sat else 0.0
    sc[F_TELOK * L + lane] = 1.0 if alive & err_ok else 0.0

    # A step that is not finite everywhere is not committed (the drone stops here).
    # (Any NaN or inf makes the sum non-finite; independent partial sums keep the
    # dependency chain short.)
    check = (((npx + npy + npz) + (nvx + nvy + nvz)) + ((nph + nth + nps) + (nwx + nwy + nwz))
             + ((ipx + ipy + ipz) + (iax + iay + iaz)) + ((udx + udy + udz) + (uadx + uady + uadz))
             + ((ncx + ncy + ncz) + (ncdx + ncdy + ncdz)) + ((sx + sy + sz) + (sax + say + saz))
             + thrust + ((nph0 + nph1 + nph2) + (nvh0 + nvh1 + nvh2)) + (nie0 + nie1 + nie2))
    finite = math.isfinite(check)
    ok = alive & err_ok & finite
    died = alive and not ok
    sc[F_ALIVE * L + lane] = 1.0 if ok else 0.0
    sc[F_DSTEP * L + lane] = kf_step if died else sc[F_DSTEP * L + lane]
    far = DIVERGED_OVERPOWERED if lf_old > LIMITED_FRACTION else DIVERGED_RUNAWAY
    why = far if (not err_ok) and err > limit else DIVERGED_NONFINITE
    why = DIVERGED_GROUND if below else why
    sc[F_REASON * L + lane] = float(why) if died else sc[F_REASON * L + lane]

    # Statistics and the commit, for the drones that flew this step.
    so = F_STAT * L + lane
    ssum, smax = sc[so + STAT_SUMSQ * L], sc[so + STAT_MAX * L]
    sdth, scount = sc[so + STAT_DTHRUST * L], sc[so + STAT_COUNT * L]
    last_thrust = sc[(F_CTRL + C_LAST_THRUST) * L + lane]
    sc[so + STAT_SUMSQ * L] = ssum + err * err if ok else ssum
    sc[so + STAT_MAX * L] = max(smax, err) if ok else smax
    sc[so + STAT_DTHRUST * L] = max(sdth, abs(thrust - last_thrust)) if ok else sdth
    sc[so + STAT_COUNT * L] = scount + 1.0 if ok else scount

    _commit(sc, F_STATE + 0, lane, npx, ok)
    _commit(sc, F_STATE + 1, lane, npy, ok)
    _commit(sc, F_STATE + 2, lane, npz, ok)
    _commit(sc, F_STATE + 3, lane, nvx, ok)
    _commit(sc, F_STATE + 4, lane, nvy, ok)
    _commit(sc, F_STATE + 5, lane, nvz, ok)
    _commit(sc, F_STATE + 6, lane, nph, ok)
    _commit(sc, F_STATE + 7, lane, nth, ok)
    _commit(sc, F_STATE + 8, lane, nps, ok)
    _commit(sc, F_STATE + 9, lane, nwx, ok)
    _commit(sc, F_STATE + 10, lane, nwy, ok)
    _commit(sc, F_STATE + 11, lane, nwz, ok)
    if outer:
        _commit(sc, F_CTRL + C_IPOS, lane, ipx, ok)
    if outer:
        _commit(sc, F_CTRL + C_IPOS + 1, lane, ipy, ok)
    if outer:
        _commit(sc, F_CTRL + C_IPOS + 2, lane, ipz, ok)
    if outer:
        _commit(sc, F_CTRL + C_UD, lane, udx, ok)
    if outer:
        _commit(sc, F_CTRL + C_UD + 1, lane, udy, ok)
    if outer:
        _commit(sc, F_CTRL + C_UD + 2, lane, udz, ok)
    if outer:
        _commit(sc, F_CTRL + C_SPREV, lane, sx, ok)
    if outer:
        _commit(sc, F_CTRL + C_SPREV + 1, lane, sy, ok)
    if outer:
        _commit(sc, F_CTRL + C_SPREV + 2, lane, sz, ok)
    _commit(sc, F_CTRL + C_IATT, lane, iax, ok)
    _commit(sc, F_CTRL + C_IATT + 1, lane, iay, ok)
    _commit(sc, F_CTRL + C_IATT + 2, lane, iaz, ok)
    _commit(sc, F_CTRL + C_UDA, lane, uadx, ok)
    _commit(sc, F_CTRL + C_UDA + 1, lane, uady, ok)
    _commit(sc, F_CTRL + C_UDA + 2, lane, uadz, ok)
    _commit(sc, F_CTRL + C_SAPREV, lane, sax, ok)
    _commit(sc, F_CTRL + C_SAPREV + 1, lane, say, ok)
    _commit(sc, F_CTRL + C_SAPREV + 2, lane, saz, ok)
    _commit(sc, F_CTRL + C_THC, lane, ncx, ok)
    _commit(sc, F_CTRL + C_THC + 1, lane, ncy, ok)
    _commit(sc, F_CTRL + C_THC + 2, lane, ncz, ok)
    _commit(sc, F_CTRL + C_THC_DOT, lane, ncdx, ok)
    _commit(sc, F_CTRL + C_THC_DOT + 1, lane, ncdy, ok)
    _commit(sc, F_CTRL + C_THC_DOT + 2, lane, ncdz, ok)
    _commit(sc, F_CTRL + C_LAST_THRUST, lane, thrust, ok)
    if outer:
        _commit(sc, F_CTRL + C_IERR, lane, nie0, ok)
    if outer:
        _commit(sc, F_CTRL + C_IERR + 1, lane, nie1, ok)
    if outer:
        _commit(sc, F_CTRL + C_IERR + 2, lane, nie2, ok)
    _commit(sc, F_CTRL + C_PHAT, lane, nph0, ok)
    _commit(sc, F_CTRL + C_PHAT + 1, lane, nph1, ok)
    _commit(sc, F_CTRL + C_PHAT + 2, lane, nph2, ok)
    _commit(sc, F_CTRL + C_VHAT, lane, nvh0, ok)
    _commit(sc, F_CTRL + C_VHAT + 1, lane, nvh1, ok)
    _commit(sc, F_CTRL + C_VHAT + 2, lane, nvh2, ok)
    _commit(sc, F_CTRL + C_INNOV, lane, in0, ok)
    _commit(sc, F_CTRL + C_INNOV + 1, lane, in1, ok)
    _commit(sc, F_CTRL + C_INNOV + 2, lane, in2, ok)
    _commit(sc, F_CTRL + C_ROTOR, lane, o1, ok)
    _commit(sc, F_CTRL + C_ROTOR + 1, lane, o2, ok)
    _commit(sc, F_CTRL + C_ROTOR + 2, lane, o3, ok)
    _commit(sc, F_CTRL + C_ROTOR + 3, lane, o4, ok)
    _commit(sc, F_CTRL + C_GATE, lane, gcount, ok)
    _commit(sc, F_CTRL + C_RESET, lane, rs0, ok)
    _commit(sc, F_CTRL + C_RESET + 1, lane, rs1, ok)
    _commit(sc, F_CTRL + C_RESET + 2, lane, rs2, ok)
    _commit(sc, F_CTRL + C_LIMITED, lane, lf_new, ok)

    if outer:  # the held outputs of the outer loop
        _commit(sc, F_CTRL + C_UHOLD, lane, ux, ok)
        _commit(sc, F_CTRL + C_UHOLD + 1, lane, uy, ok)
        _commit(sc, F_CTRL + C_UHOLD + 2, lane, uz, ok)
        _commit(sc, F_CTRL + C_RHOLD, lane, rph_out, ok)
        _commit(sc, F_CTRL + C_RHOLD + 1, lane, rth_out, ok)
        _commit(sc, F_CTRL + C_RPREV, lane, rpp, ok)
        _commit(sc, F_CTRL + C_RPREV + 1, lane, rtp, ok)
        _commit(sc, F_CTRL + C_UNORM, lane, un, ok)
        _commit(sc, F_CTRL + C_LIMHOLD, lane, 1.0 if limited else 0.0, ok)
        _commit(sc, F_CTRL + C_PUSHHOLD, lane, 1.0 if push else 0.0, ok)


@nb.njit(parallel=True, cache=True, error_model="numpy",
         fastmath={"nsz", "afn", "contract", "reassoc"})
def _kernel(
    state, ctrl, stats, dstep, dreason, breaks, coeffs, cursor0, times, offset, yaw, dist, step0, every,
    frames, tel, use_tel, prm, plt, gn, drag, dt, limit, drone, gnss, gnss_every, gnss_first, wtab, wind_k0,
    wind_dt, wgrad, wrad, use_gnss, use_motor, use_drag, use_clock, est_kp, est_kv, gate_h, gate_v, gate_n, reset_v,
    ground_z, batt_end,
):
    n = state.shape[0]
    steps = times.shape[0]
    last_piece = breaks.shape[1] - 2
    # Controller model (what the controller believes).
    m = prm[0]
    ix, iy, iz = prm[1], prm[2], prm[3]
    g = prm[7]
    # The plant's rotors (its mass and inertia are per drone, in ``drone``).
    arm, kf, km, pg, wmax2 = plt[4], plt[5], plt[6], plt[7], plt[8]
    k1, k2, r1, r2, alpha = gn[0], gn[1], gn[2], gn[3], gn[4]
    k3, k4, r3, r4, beta_g = gn[5], gn[6], gn[7], gn[8], gn[9]
    # The laws' powers as the exponents of x·x (``_sig_scale``).
    h1, h2, h3, h4 = 0.5 * (r1 - 1.0), 0.5 * (r2 - 1.0), 0.5 * (r3 - 1.0), 0.5 * (r4 - 1.0)
    wn, zeta = gn[10], gn[11]
    eps_p, eps_pq, eps_a, eps_aq, ki, ilim, izone = gn[12], gn[13], gn[14], gn[15], gn[16], gn[17], gn[18]
    uz_min, tan_tilt = gn[19], gn[20]
    desat = gn[21] > 0.5  # PX4's sequential desaturation (else the paper's per-rotor clip)
    wmax2_yaw = (1.0 + YAW_HEADROOM) * wmax2
    # Reciprocals of the constants, hoisted: a multiply is ~5x cheaper than a divide.
    inv_ix, inv_iy, inv_iz = 1.0 / ix, 1.0 / iy, 1.0 / iz
    inv_2akf, inv_4km = 1.0 / (2.0 * arm * kf), 1.0 / (4.0 * km)
    n_wind = wtab.shape[0]
    blocks = (n + LANES - 1) // LANES
    L = LANES
    kev = int(gn[22])  # the outer loop runs every kev steps (IsmcGains.outer_every), with step dto
    dto = float(kev) * dt
    cst = (m, ix, iy, iz, g, arm, kf, km, pg, wmax2, k1, k2, h1, h2, alpha, k3, k4, h3, h4, beta_g, wn, zeta,
           eps_p, eps_pq, eps_a, eps_aq, ki, ilim, izone, uz_min, tan_tilt, wmax2_yaw, inv_ix, inv_iy, inv_iz,
           inv_2akf, inv_4km, limit, ground_z, reset_v, dt, dto, drag, wrad, est_kp, est_kv, gate_h, gate_v,
           gate_n)
    flg = (desat, use_clock, use_gnss, use_motor, use_drag)

    for b in nb.prange(blocks):
        i0 = b * L
        cnt = min(L, n - i0)
        sc = _aligned_zeros(NF * L)
        nl = sc.size // NF
        cur = np.zeros(L, dtype=np.int64)
        nxt = np.zeros(L)
        prv = np.zeros(L)
        curc = np.zeros(L, dtype=np.int64)
        nxtc = np.zeros(L)
        prvc = np.zeros(L)
        # ---- fill the scratch (lanes past the fleet fly a copy of its last drone, never stored)
        for lane in range(L):
            i = min(i0 + lane, n - 1)
            for f in range(12):
                sc[(F_STATE + f) * L + lane] = state[i, f]
            for f in range(CTRL_SIZE):
                sc[(F_CTRL + f) * L + lane] = ctrl[i, f]
            for f in range(D_SIZE):
                sc[(F_DRONE + f) * L + lane] = drone[i, f]
            sc[(F_INV + 0) * L + lane] = 1.0 / drone[i, D_IX]
            sc[(F_INV + 1) * L + lane] = 1.0 / drone[i, D_IY]
            sc[(F_INV + 2) * L + lane] = 1.0 / drone[i, D_IZ]
            sc[(F_INV + 3) * L + lane] = 1.0 / drone[i, D_MASS]
            sc[F_TF * L + lane] = breaks[i, 0]
            sc[F_TL * L + lane] = breaks[i, last_piece + 1]
            for f in range(STATS_SIZE):
                sc[(F_STAT + f) * L + lane] = stats[i, f]
            sc[F_ALIVE * L + lane] = 1.0 if dstep[i] < 0 else 0.0
            sc[F_DSTEP * L + lane] = float(dstep[i])
            sc[F_REASON * L + lane] = float(dreason[i])
            c0 = cursor0[i]
            cur[lane], curc[lane] = c0, c0
            nxt[lane] = breaks[i, c0 + 1] if c0 < last_piece else math.inf
            prv[lane] = breaks[i, c0] if c0 > 0 else -math.inf
            nxtc[lane], prvc[lane] = nxt[lane], prv[lane]
            _load_piece(sc, F_REF, lane, coeffs, breaks, i, c0)
            _load_piece(sc, F_REFC, lane, coeffs, breaks, i, c0)
        win_lo, win_hi = math.inf, -math.inf  # empty: the first step searches
        # Next frame step, advanced by a counter (an integer division per step costs ~5 %).
        next_rec = ((step0 + every - 1) // every) * every
        next_outer = ((step0 + kev - 1) // kev) * kev
        next_gnss = gnss_first
        gidx = 0
        iw_loaded = -1
        for j in range(steps):
            k = step0 + j
            t = times[j]
            rec = k == next_rec
            if rec:
                next_rec += every
                fr = k // every
                for lane in range(cnt):
                    frames[fr, i0 + lane, 0] = sc[(F_STATE + 0) * L + lane]
                    frames[fr, i0 + lane, 1] = sc[(F_STATE + 1) * L + lane]
                    frames[fr, i0 + lane, 2] = sc[(F_STATE + 2) * L + lane]
            # ---- the scalar part: pieces, GNSS and wind table rows (uniform or rare)
            # The piece cursors: while t stays inside the block's common window no lane can
            # leave its piece (see ``_block_window``), which is most steps: two comparisons
            # instead of a pass over the lanes.
            if not (win_lo <= t < win_hi):
                for lane in range(L):
                    i = min(i0 + lane, n - 1)
                    tf, tl = sc[F_TF * L + lane], sc[F_TL * L + lane]
                    _seek(sc, F_REF, lane, cur, nxt, prv, coeffs, breaks, i, min(max(t, tf), tl), last_piece)
                    if use_clock:
                        tcc = min(max(t + sc[(F_DRONE + D_CLOCK) * L + lane], tf), tl)
                        _seek(sc, F_REFC, lane, curc, nxtc, prvc, coeffs, breaks, i, tcc, last_piece)
                win_lo, win_hi = _block_window(sc, nxt, prv, nxtc, prvc, use_clock)
            epoch = use_gnss and k == next_gnss
            if epoch:  # a GNSS epoch: the lanes take a new innovation z - p̂, held until the next
                for lane in range(L):
                    i = min(i0 + lane, n - 1)
                    for a in range(3):
                        sc[(F_GNSS + a) * L + lane] = gnss[gidx, i, a]
                next_gnss += gnss_every
                gidx += 1
            fw = 0.0
            if use_drag:  # the wind, linear on its grid: the rows around t
                xw = t / wind_dt
                iw = min(max(int(math.floor(xw)) - wind_k0, 0), n_wind - 2)
                fw = xw - (wind_k0 + iw)
                if iw != iw_loaded:
                    iw_loaded = iw
                    for lane in range(L):
                        i = min(i0 + lane, n - 1)
                        for a in range(3):
                            sc[(F_WA + a) * L + lane] = wtab[iw, i, a]
                            sc[(F_WB + a) * L + lane] = wtab[iw + 1, i, a]
                        for a in range(WIND_GRAD_SIZE):
                            sc[(F_WJ + a) * L + lane] = 0.5 * (wgrad[iw, i, a] + wgrad[iw + 1, i, a])
            off0, off1, off2 = offset[j, 0], offset[j, 1], offset[j, 2]
            off3, off4, off5 = offset[j, 3], offset[j, 4], offset[j, 5]
            off6, off7, off8 = offset[j, 6], offset[j, 7], offset[j, 8]
            rps, ysin, ycos = yaw[j, 0], yaw[j, 1], yaw[j, 2]
            dx0, dx1, dx2 = dist[j, 0], dist[j, 1], dist[j, 2]
            dw0, dw1, dw2 = dist[j, 3], dist[j, 4], dist[j, 5]
            d2x, d2y, d2z = dist[j, 6], dist[j, 7], dist[j, 8]
            kf_step = float(k)
            t_batt = min(t, batt_end)  # the battery sag grows until the pack's endurance, then is held

            # ---- the vector part: one control + integration step of every lane. (The trip
            # count is read from the scratch's size, not the constant LANES: LLVM fully
            # unrolls a loop with a small constant trip count before it could vectorise it.)
            outer = k == next_outer
            if outer:
                next_outer += kev
            # The step's place in the outer loop's period (0 when it runs) and the ramp's weight.
            phase = k - (next_outer - kev)
            wgt = float(kev - 1 - phase) / float(kev)
            stp = (t, off0, off1, off2, off3, off4, off5, off6, off7, off8, rps, ysin, ycos, dx0, dx1, dx2,
                   dw0, dw1, dw2, d2x, d2y, d2z, kf_step, t_batt, fw, wgt)
            # The outer loop runs at steps k = 0 mod K (a counter, as the frames'), uniform over the
            # lanes: the branch sits outside the lane loops, one loop body each (``_lane_step``).
            if outer:
                for lane in range(nl):
                    _lane_step(sc, lane, True, epoch, cst, flg, stp)
            else:
                for lane in range(nl):
                    _lane_step(sc, lane, False, epoch, cst, flg, stp)
            if use_tel and rec:
                fr = k // every
                for lane in range(cnt):
                    if sc[F_TELOK * L + lane] > 0.5:
                        for f in range(TEL_SIZE):
                            tel[fr, i0 + lane, f] = sc[(F_TEL + f) * L + lane]

        # ---- write the block back
        for lane in range(cnt):
            i = i0 + lane
            for f in range(12):
                state[i, f] = sc[(F_STATE + f) * L + lane]
            for f in range(CTRL_SIZE):
                ctrl[i, f] = sc[(F_CTRL + f) * L + lane]
            for f in range(STATS_SIZE):
                stats[i, f] = sc[(F_STAT + f) * L + lane]
            dstep[i] = int(sc[F_DSTEP * L + lane])
            dreason[i] = int(sc[F_REASON * L + lane])


def run_chunk_numba(
    state: np.ndarray, ctrl: np.ndarray, stats: np.ndarray, dstep: np.ndarray,
    dreason: np.ndarray, *, ref: TrackingReference, chunk: RefChunk, dist: np.ndarray,
    step0: int, times: np.ndarray, every: int, frames: np.ndarray, tel: np.ndarray | None,
    opts: dict[str, Any], tables: ChunkTables | None = None,
) -> None:
    """Advance ``len(times)`` steps in place with the lane kernel (same contract as the numpy chunk).

    Args:
        state: ``(N, 12)`` plant states, updated in place.
        ctrl: ``(N, CTRL_SIZE)`` controller states, updated in place.
        stats: ``(N, STATS_SIZE)`` running statistics, updated in place.
        dstep: ``(N,)`` divergence step (-1 while flying), updated in place.
        dreason: ``(N,)`` divergence reason code, updated in place.
        ref: The drones' reference (their polynomial pieces, m).
        chunk: The shared reference tables at ``times``.
        dist: ``(T, 9)`` disturbance signals at ``times``.
        step0: Index of the first step of the chunk.
        times: ``(T,)`` step times (s).
        every: Frame decimation (steps per output frame).
        frames: ``(F, N, 3)`` output positions (m), written at frame steps.
        tel: ``(F, N, TEL_SIZE)`` telemetry or None.
        opts: ``params``, ``plant``, ``gains``, ``disturbance``, ``dt_s``,
            ``divergence_limit_m``, optionally ``drone``, ``switches`` and ``ground_strike_z_m``,
            as in the numpy engine.
        tables: The chunk's GNSS and wind tables (None: ideal).
    """
    args = _kernel_args(state, ctrl, stats, dstep, dreason, ref=ref, chunk=chunk, dist=dist, step0=step0,
                        times=times, every=every, frames=frames, tel=tel, opts=opts, tables=tables)
    _cached_machine_code(_kernel, args)
    _kernel(*args)



def _kernel_args(
    state: np.ndarray, ctrl: np.ndarray, stats: np.ndarray, dstep: np.ndarray,
    dreason: np.ndarray, *, ref: TrackingReference, chunk: RefChunk, dist: np.ndarray,
    step0: int, times: np.ndarray, every: int, frames: np.ndarray, tel: np.ndarray | None,
    opts: dict[str, Any], tables: ChunkTables | None = None,
) -> tuple[Any, ...]:
    """The lane kernel's arguments for one chunk (checked); shared with the float32 kernel
    (:mod:`sim.flight.engines._numba_f32`, same signature). Arguments as :func:`run_chunk_numba`."""
    sw: ErrorSwitches = opts.get("switches") or ErrorSwitches()
    drone = opts.get("drone")
    if drone is None:
        drone = ideal_drone_constants(opts["plant"], state.shape[0])
    if tables is None:
        tables = ChunkTables.empty(state.shape[0])
    if (sw.gnss and tables.gnss.shape[0] == 0 and times.size
            and (step0 + times.size - 1) // tables.gnss_every >= -(-step0 // tables.gnss_every)):
        raise ValueError("the GNSS error model needs the chunk's GNSS table")
    if sw.drag and tables.wind.shape[0] < 2:
        raise ValueError("quadratic drag needs the chunk's wind table")
    if sw.drag and tables.wind_grad.shape != (*tables.wind.shape[:2], WIND_GRAD_SIZE):
        raise ValueError("the wind's derivative table must match its wind table")
    use_tel = tel is not None
    tel_arr = tel if use_tel else np.zeros((0, 0, TEL_SIZE))
    motion = ref.motion
    # Each drone's piece at the chunk's first step (one search per chunk); the kernel
    # advances from there.
    cursor0 = _rw(motion.piece_index(chunk.times[:1])[0], np.int64)
    return (
        state, ctrl, stats, dstep, dreason, _rw(motion.breaks_s), _rw(motion.coeffs_m), cursor0,
        _rw(chunk.times), _rw(chunk.offset), _rw(chunk.yaw), _rw(dist), int(step0), int(every),
        frames, tel_arr, use_tel, _rw(opts["params"].as_vector()), _rw(opts["plant"].as_vector()),
        _rw(opts["gains"].as_vector(float(opts["dt_s"]))), float(opts["disturbance"].drag_per_s),
        float(opts["dt_s"]), float(opts["divergence_limit_m"]), _rw(drone),
        _rw(tables.gnss), int(tables.gnss_every), int(tables.gnss_first),
        _rw(tables.wind), int(tables.wind_k0), float(tables.wind_dt_s), _rw(tables.wind_grad),
        float(tables.wind_radius_m),
        bool(sw.gnss), bool(sw.motor), bool(sw.drag), bool(sw.clock), float(sw.est_kp), float(sw.est_kv),
        float(sw.gate_h_m), float(sw.gate_v_m), float(sw.gate_epochs), float(sw.reset_mps),
        float(opts.get("ground_strike_z_m", -math.inf)), float(sw.battery_end_s),
    )


def _rw(a: Any, dtype: type = np.float64) -> np.ndarray:
    """``a`` as a writable C-contiguous array of ``dtype`` (copied only when it is not one already).

    Why writable: numba types a read-only array as a different type and compiles a second
    specialisation of the kernel for it, whose machine code may contract or vectorise differently
    (1e-13 m level differences). Arrays that arrive through Dask's pickle-5 buffers are sometimes
    read-only, depending on how the message was framed, so a shard could run the other binary
    than the local engine and break the bit-identical local/Dask guarantee.
    """
    return np.require(a, dtype=dtype, requirements=["C", "W"])


def _cached_machine_code(dispatcher: Any, args: tuple[Any, ...]) -> None:
    """Make this process run ``dispatcher``'s machine code for ``args`` *as loaded from numba's disk cache*.

    Why: for this parallel kernel numba's in-process JIT and the object code it writes to the
    cache differ in the last bit of some results (measured: 2e-14 m after 2 s of flight, then
    amplified by the finite-time laws' chatter), and once a process has JIT-compiled the
    kernel, loading the cached code later does not help (its ``prange`` body keeps resolving
    to the JIT-compiled one). A process that compiled the kernel would then disagree bit for
    bit with every process that loaded it from the cache: a Dask worker, the next CLI run.
    So on a cache miss the specialisation is compiled (and cached) by a child process, and this
    process loads the cached code like every other. If the child cannot do it (cache not
    writable, caching off) this process compiles as numba always does; only then can processes
    differ, at that rounding level. Uses numba's dispatcher internals (``_cache``); if they
    change, this falls back to numba's own behaviour.
    """
    try:
        sig = tuple(dispatcher.typeof_pyval(a) for a in args)
        if sig in dispatcher.overloads:
            return
        if not _in_disk_cache(dispatcher, sig):
            _log.warning(COMPILE_NOTE)
            func = dispatcher.py_func
            # The child's first statement lifts its soft data limit to the hard one: a server's worker
            # caps its data (app.tasks.limit_memory, 2 GiB by default) and LLVM compiling the two lane
            # bodies needs ~2.6 GiB. In the child's own code, not a ``preexec_fn``: that runs between
            # fork and exec, which is unsafe in a process with threads (a worker has them).
            code = (f"{_LIFT_DATA_LIMIT}; import pickle, sys, importlib; "
                    f"f = getattr(importlib.import_module({func.__module__!r}), {func.__qualname__!r}); "
                    "f.compile(pickle.loads(sys.stdin.buffer.read()))")
            # The child imports this process's code: its sys.path as PYTHONPATH ('' is the working
            # directory), and ``-P`` so that the child's own working directory does not come first
            # (another checkout's ``sim`` there was imported instead, and this process compiled).
            env = dict(os.environ, PYTHONPATH=os.pathsep.join(p or os.getcwd() for p in sys.path))
            # No short timeout: at a timeout this process compiles the kernel itself from the start
            # (slower, and its bits differ from the cache's); a compile measured 28-32 min of wall
            # time at a load of 8-10 on this 2-core machine (351 s of CPU alone).
            done = subprocess.run([sys.executable, "-P", "-c", code], input=pickle.dumps(sig), env=env,
                                  capture_output=True, timeout=_COMPILE_TIMEOUT_S, check=False)
            if done.returncode != 0:
                tail = done.stderr.decode(errors="replace").strip().splitlines()[-3:]
                _log.warning("the flight kernel's compiling process failed (%s); compiling here instead",
                             " / ".join(tail) or f"exit {done.returncode}")
    except (AttributeError, OSError, subprocess.SubprocessError, pickle.PicklingError):  # pragma: no cover
        return
    dispatcher.compile(sig)  # from the cache when the child wrote it


def _in_disk_cache(dispatcher: Any, sig: tuple[Any, ...]) -> bool:
    """Whether numba's disk cache holds ``dispatcher``'s machine code for the argument types ``sig``.

    It loads the code (the index file names the signature, target machine and source stamp; the
    data file holds the object code), so a stale or foreign entry counts as missing, as it does
    for numba. Uses numba's dispatcher internals (``_cache``), like :func:`_cached_machine_code`.
    """
    return bool(dispatcher._cache.load_overload(sig, dispatcher.targetctx) is not None)

"""Radial velocity and depth from a set of D-ToF measurements (pure numpy).

A rendered D-ToF pixel is the exposure average of the low-pass correlation

    m = (1/T) ∫_0^T (g1/2) Λ(2π h t/T + ψ + k L(t)) A dt,      k = 2π f_g / c,

with L(t) the optical path length (m) and A the radiance of the path. For the sinusoid
(Λ = cos) and one path with constant A and L(t) = L0 + u t this has the closed form

    m = (g1/2) Re{ Z e^{iψ} F(2π h + a) },   Z = A e^{i k L0},   a = k u T,
    F(x) = (e^{ix} − 1)/(i x),   F(0) = 1,

i.e. m = (g1 A/2) [sin(θ + 2πh + a) − sin θ]/(2πh + a) with θ = ψ + k L0. Everything in
this module inverts that model per pixel. With the light co-located with the camera the
path length is twice the distance, so u = 2 v (v the radial velocity, positive when the
distance grows) and the reported depth is d = L/2.

Brightness. A moving surface does not keep its radiance: lit from the camera, it follows
the inverse-square law, A ∝ 1/d(t)², a relative change β = −2 v T/d over the exposure. That
is as large as the Doppler phase itself (β/a = −c/(2π f_g d): −0.4 at 30 MHz and 4 m), and
it enters the heterodyne measurements like a Doppler shift turned by 90°: to first order a
heterodyne pair measures (a + iβ) Z/2π. The model therefore has four unknowns per pixel,
Z (amplitude and depth phase), a and β, with

    A(τ)/A_mid = 1 + β (τ − ½) + ¾ β² (τ − ½)²      (τ = t/T, the inverse square to 2nd order),

    m_i = (g1_i/2) Re{ Z K_i },   K_i = e^{iψ_i} [F(x_i) + β G(x_i) + ¾ β² H(x_i)],

x_i = 2π h_i + a, G(x) = ∫_0^1 (s − ½) e^{ixs} ds, H(x) = ∫_0^1 (s − ½)² e^{ixs} ds (the
curvature term matters: without it the fit read +0.0046 m/s too high at ±10 m/s and 5 m,
about twice the standard error of a Cornell-box pixel at 64² and 4096 spp). A camera set whose measurements cannot tell a from β — three cameras (h = 0 at one
phase, h = 1 at two: the homodyne gives only Re Z), or a single h = 0/h = 1 pair — cannot
determine velocity and is refused, naming the cameras to add (h = 0 at the missing phase).

Two estimators:

``"ratio"`` (Heide et al. 2015, the original code's ``calc_velocity_from_homo_hetero(s)``)
    pairs each homodyne camera (h = 0) with a heterodyne one (h = 1) at the same ψ. For the
    sinusoid E/H = a/(a + 2π) *exactly* (the exposure-average of cos over the beat cancels
    the phase), so a = 2π r/(1 − r) with r = E/H, i.e. v = c r / (2 f_g T (1 − r)), the
    original formula; no small-r approximation (c is the exact ``SPEED_OF_LIGHT_M_S``
    here, where the original used 3e8). Several phases are fused by the least-squares
    slope of E against H, r̄ = Σ E_i H_i / Σ H_i², then inverted exactly as above.

    Why not the original r̄ = Σ r_i |H_i| / Σ |H_i|: it assumes the radiance is constant
    during the exposure. If it changes linearly, A(t) = A₀ (1 + β (t/T − ½)) (a surface
    that moves closer brightens as 1/d²), every heterodyne image gains
    β A₀ (g1/2) sin θ_i / 2π at a = 0, so r_i gains β tan θ_i / 2π, which the |H|-weighted
    mean keeps, while Σ E_i H_i gains ∝ β Σ sin 2θ_i, zero as soon as Σ e^{2iψ_i} = 0
    (ψ = 0, π/2; or 0, π/2, π, 3π/2). What is left is second order: the velocity is
    scaled by ≈ 1 − β²/12, and the inverse square's curvature, ¾ β², adds +0.0046 m/s at
    ±10 m/s and 5 m (∝ v²/d²). Pairs whose phases do not balance are refused
    (use the fit). The slope divides by no single H_i, so every pair enters it:
    leaving out pairs by their own r_i (small |H_i|, r_i ≥ 1) would select on noise and
    undo the cancellation. Other waveforms are accepted but the ratio is then only
    approximately a/(a + 2π).
``"fit"``
    any set that determines a and β (≥ 4 measurements), sinusoid only: for fixed a and β
    the model is linear in (Re Z, Im Z) and solved in closed form (2×2 normal equations);
    a is found per pixel by a coarse grid over ``|Δf| ≤ max_doppler_hz`` (at β = 0), then
    a and β by variable-projection Gauss-Newton steps with step halving. Exact for the
    brightness model above. Covers homodyne + heterodyne at several phases and arbitrary
    heterodyne schemes such as Hu et al. 2022 (h ∈ {½, ½, −½, −½}, ψ ∈ {3π/2, 0, π/2, π}).

``"auto"`` is the fit for sinusoids and the ratio otherwise.

Errors. Given the measurements' covariance (a render's per-camera standard errors and
``measurement_covariance``), the velocity and depth errors are propagated by the delta
method: the fit's gradient is its Gauss-Newton linearisation, the ratio's its closed form.
A pixel is valid when its velocity's standard error is at most ``max_velocity_stderr``
(:func:`default_max_velocity_stderr`). These are Monte Carlo errors: a pixel that sees
several paths (global illumination, a silhouette) is biased beyond them.

Depth refers to the middle of the exposure (t = T/2): the phase of the homodyne
correlation is exactly k L(T/2) whatever the velocity, so a 4-phase homodyne depth is
exact at mid-exposure even for a moving target. Depth is reported modulo the ambiguity
range c/(2 f_g) (``VelocityResult.depth_range_m``). Cameras at two modulation frequencies
(sharing T and the first window) are reconstructed frequency by frequency, their
velocities averaged and their depths unwrapped to c/(2 |f_1 − f_2|)
(:mod:`dopplertof.reconstruct.frequencies`).

Capture schedules. Cameras may expose at different times (``exposure_start``, s: a
render's cameras one after another, docs/reconstruction.md, "Capture schedules"). The model then takes
each pixel to see *one* path over the whole schedule, its length growing at a constant
rate and its radiance constant (β = 0: with β free, four windows of four cameras leave
several exact solutions): camera i, whose window opens δ_i = (s_i − s_0)/T
exposures after the first camera's, sees the path lengthened by u (s_i − s_0), so its
phase gains a δ_i:

    m_i = (g1_i/2) Re{ Z e^{i(ψ_i + a δ_i)} F(2π h_i + a) },   Z = A e^{i k L(s_0)},

and depth and amplitude refer to the first camera's window. This is exact for a surface
receding at constant speed (up to its 1/d² brightening), and wrong wherever a pixel sees
different surfaces in different windows (a moving edge: the motion artefact of sequential
capture), the motion accelerates, or the radiance changes between windows. Every
estimator uses this model; the ratio pairs a homodyne with a heterodyne camera of the
same window; the fit searches a grid 1 + max δ_i times finer and refines its deepest few
minima, since later windows give distant Doppler phases residuals almost as small as the
true one's. Cameras without ``exposure_start`` (None) share the first window; a set that
mixes None with given starts is refused (pass the render's ``result.cameras``, whose
starts are filled in).

Parameters shared by the public functions:

=====================  ======  ===========================  ===================================
name                   unit    default                      meaning
=====================  ======  ===========================  ===================================
``measurements``       –       required                     array (n_cameras, ...) of rendered
                                                            measurements, one image per camera
``cameras``            –       required                     sequence of n_cameras objects with
                                                            ``modulation_frequency`` (Hz),
                                                            ``exposure`` (s), ``heterodyne``,
                                                            ``phase`` (rad), ``waveform``,
                                                            ``g1``, optionally
                                                            ``exposure_start`` (s); all must
                                                            share T, and one or two f_g
``min_amplitude``      meas.   1e-3 × 99th percentile       pixels whose signal amplitude
                               of the image's amplitude     (max_i |H_i| for the ratio,
                                                            |H_i| for a per-phase ratio,
                                                            (g1/2)|Z| for the fit and depth)
                                                            is not above it are invalid
``method``             –       ``"auto"``                   ``"ratio"``, ``"fit"`` or ``"auto"``
                                                            (the fit for sinusoids, else the
                                                            ratio)
``max_doppler_hz``     Hz      1/(2T)                       search range of the fit, |Δf|;
                                                            |a| ≤ π at the default
=====================  ======  ===========================  ===================================

Invalid pixels (amplitude too small, r ≥ 1, non-finite input, Doppler outside the search
range, velocity not identifiable at that pixel) have ``valid == False`` and NaN velocity.
"""

from .errors import DEFAULT_RELATIVE_MAX_VELOCITY_STDERR, UNSCALED_MAX_VELOCITY_STDERR_M_S, default_max_velocity_stderr
from .estimate import MIN_STDERR_DOF, VelocityResult, depth, unambiguous_speed_m_s, velocity
from .model import DEFAULT_RELATIVE_MIN_AMPLITUDE, SPEED_OF_LIGHT_M_S, ambiguity_range_m, model_measurements
from .ratio import RatioPhaseResult, ratio_velocity_per_phase

__all__ = [
    "DEFAULT_RELATIVE_MAX_VELOCITY_STDERR", "DEFAULT_RELATIVE_MIN_AMPLITUDE", "MIN_STDERR_DOF", "SPEED_OF_LIGHT_M_S", "RatioPhaseResult",
    "VelocityResult", "ambiguity_range_m", "default_max_velocity_stderr", "depth", "model_measurements",
    "UNSCALED_MAX_VELOCITY_STDERR_M_S", "ratio_velocity_per_phase", "unambiguous_speed_m_s", "velocity",
]

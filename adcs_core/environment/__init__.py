"""The environment the attitude sensors see: orbit, Sun, Earth's shadow, Earth's magnetic field, and
the frames they are written in (kernel: numpy/scipy plus ``sgp4`` and ``ppigrf``; no ROS).

Modules: :mod:`.frames` (time scales, Earth rotation angle, ECI <-> ECEF, geodetic coordinates, NED/ENU),
:mod:`.sun` (Astronomical Almanac low-precision solar ephemeris), :mod:`.eclipse` (cylindrical and conical
shadow), :mod:`.magnetic` (IGRF and the tilted dipole), :mod:`.tle` (SGP4 orbits and the circular orbit
behind one interface), :mod:`.environment` (:class:`Environment`, :func:`build_environment`).

Conventions (written once, here; every module of the package follows them)
-------------------------------------------------------------------------
Units
    SI throughout: metres, seconds, radians, tesla. (The libraries work in km, km/s, degrees and nT;
    the wrappers convert at the boundary.) The Sun's distance is in metres too (1 au = 149 597 870 700 m).
Time
    A scenario has an epoch, a UTC instant written as an ISO-8601 string (``"2026-03-20T12:00:00Z"``;
    no offset means UTC). Everything inside takes ``t``, seconds since that epoch, turned into *days since
    J2000.0* ``d = JD - 2451545.0`` (a float with ~0.2 µs resolution, the form the IERS formulas use).
    UT1 is taken equal to UTC (|UT1 - UTC| < 0.9 s by the definition of UTC: at most 66 µrad of Earth
    rotation, ~0.4 km along the equator at LEO radius); TT = UTC + 69.184 s (TAI - UTC = 37 s since
    2017, TT - TAI = 32.184 s; a future leap second would change it by 1 s, below every use made of TT
    here: it only enters centuries of precession). Leap seconds themselves (``23:59:60``) are refused.
ECI
    "ECI" in this package is the *celestial intermediate frame* of IERS Conventions 2010 ch. 5 (CIRS):
    z along the celestial intermediate pole, x at the celestial intermediate origin, i.e. exactly the
    frame that one rotation about z by the Earth rotation angle (ERA, IERS 2010 eq. 5.15) takes to the
    Earth-fixed frame: ``r_ECEF = R3(ERA) r_ECI``. Polar motion is neglected (ECEF = TIRS; |x_p|, |y_p| <
    0.6", < 20 m at the Earth's surface) and so is precession-nutation between this frame and the GCRF
    (the J2000-like ICRF axes): the CIRS pole is off the GCRF pole by sqrt(X^2 + Y^2) ~ 2004" per century
    since J2000 (~0.15 deg in 2026) plus nutation (< 20"); its x axis (the CIO) stays within mas of the
    GCRF x axis. For attitude simulation the frame only needs to be inertial to well below a sensor's
    accuracy over a run, which it is (its axes move by ~20"/yr).
TEME (SGP4) and the Sun's mean-of-date coordinates
    SGP4 (Vallado, Crawford, Hujsak & Kelso 2006, "Revisiting Spacetrack Report #3", AIAA 2006-6753)
    gives positions in TEME: true equator (z along the true pole of date, the same pole as ours to mas)
    and a *mean equinox* x axis, taken to Earth-fixed axes by GMST (their eq. for TEME -> PEF). The
    Almanac's solar formula gives mean-equator-of-date coordinates with an equinox x axis. Both differ
    from our ECI by a rotation about z through GMST - ERA (the accumulated precession in right
    ascension, IERS 2010 eq. 5.32 minus eq. 5.15; +0.34 deg in 2026), which :func:`.frames.equinox_to_eci`
    applies, so that a TLE satellite's Earth-fixed position is the one SGP4 means (R3(GMST) r_TEME). The
    residuals are the equation of the equinoxes and the MOD/TOD nutation (< 20", below the Sun
    formula's 0.01 deg) and GMST82 vs GMST2006 (< 1 mas).
Orbit frame and attitude
    The orbit frame is :mod:`adcs_core.orbit`'s (x along track, z to nadir). Quaternions are Hamilton,
    scalar last ``(x, y, z, w)``, of the body frame in the inertial frame (``R(q)`` maps body vectors to
    ECI), as :mod:`adcs_core.attitude`.
Batch axis
    Every function takes a leading batch axis (times and/or runs): positions ``(..., 3)``, times
    ``(...)``. Products are written in a fixed order (no BLAS reductions), so an element computed alone
    has the same bits as inside a batch (tests/test_environment_model.py checks it).

This package module imports nothing: import the modules themselves (``magnetic`` brings ``ppigrf`` and
pandas, about 1 s of import; the parameter schemas only need :mod:`.options`, :mod:`.frames` and
:mod:`.tle`).
"""

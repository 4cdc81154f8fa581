"""One contract, every registered transport (as Mitsuba runs one suite over its ``INTEGRATORS``): a thick slab under
uniform light exits ``R_total E``; a point source reproduces ``R_d(r)``; a lit sphere agrees with the exact sum;
the same inputs give the same output bit for bit; relit with other irradiance, a transport answers as one built for
it; exitance is never negative; parameters are declared and checked."""

import numpy as np
import pytest

from convsss import material
from convsss.errors import ConvsssError
from convsss.profiles import model_profile
from convsss.samples import IrradianceSamples, ViewFrame
from convsss.transport import TRANSPORTS, make_transport

FRAME = ViewFrame.look_at(origin=[0, 0, 50], target=[0, 0, 0])
KINDS = sorted(TRANSPORTS)
#: Per transport, settings that make it accurate on these small cases (the contract is about correctness).
ACCURATE = {"convolution": {"layers": 16, "threshold": 0.0, "resolution": 256}, "hierarchical": {"epsilon": 0.01},
            "multiscale": {"accuracy": 0.001}, "volume": {"accuracy": 0.001}}


def _make(kind, samples, profile, medium, **params):
    """The transport ``kind`` of ``profile``, the model of the material ``medium``."""
    return make_transport(kind, samples, profile, FRAME, medium, **{**ACCURATE.get(kind, {}), **params})


def _slab(half_width, spacing):
    n = int(np.ceil(2 * half_width / spacing))
    xs = (np.arange(n) + 0.5) * spacing - n * spacing / 2
    x, y = np.meshgrid(xs, xs)
    position = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    return IrradianceSamples(position, spacing**2, np.ones((len(position), 3)),
                             np.tile([0.0, 0.0, 1.0], (len(position), 1)))


def _sphere(n=3000, radius=2.0):
    k = np.arange(n) + 0.5
    phi, theta = np.arccos(1 - 2 * k / n), np.pi * (1 + 5**0.5) * k
    normal = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)
    lit = np.maximum(normal @ (np.array([0.6, 0.3, 0.74]) / np.linalg.norm([0.6, 0.3, 0.74])), 0.0)
    return IrradianceSamples(normal * radius, 4 * np.pi * radius**2 / n, lit[:, None] * np.ones(3), normal)


def test_every_transport_registers_itself_with_declared_parameters():
    assert {"exact", "convolution", "hierarchical"} <= set(TRANSPORTS)
    for kind, cls in TRANSPORTS.items():
        assert cls.name == kind
        names = [p.name for p in cls.parameters]
        assert len(names) == len(set(names)) and all(p.help for p in cls.parameters)


@pytest.mark.parametrize("kind", KINDS)
def test_slab_exits_total_reflectance(kind):
    skin = model_profile("dipole", material("skin1"))
    slab = _slab(25.0, 0.25)
    centre = np.array([[0.0, 0.0, 0.0], [0.5, -0.5, 0.0]])
    exitance = _make(kind, slab, skin, material("skin1")).exitance(centre)
    np.testing.assert_allclose(exitance, np.tile(skin.total_reflectance, (2, 1)), rtol=0.01)


#: Measured shortfalls, each a strict xfail: it fails today, and passes (failing the suite) once fixed.
SHORT = {"volume": "a single source's response on the grid differs from the table averaged over where it falls "
                   "within a cell: along a grid axis it swings by up to 10-13 % with a period of three cells from 1 "
                   "to 2.6 mm, and is 18 % low at 0.2 mm, under one cell, in green and blue (wholemilk, auto "
                   "spacing 0.28 mm)"}


@pytest.mark.parametrize("kind", [pytest.param(k, marks=[pytest.mark.xfail(strict=True, reason=SHORT[k]),
                                                           pytest.mark.slow])  # 13 s: the full suite's
                                  if k in SHORT else k for k in KINDS])
def test_point_source_reproduces_the_profile(kind):
    """A unit flux at the centre of an unlit grid of samples (cell = mfp/4): M(r) = R_d(r) beyond three cells."""
    milk = material("wholemilk")
    cell = milk.mfp_mm.min() / 4
    xs = (np.arange(101) - 50) * cell
    x, y = np.meshgrid(xs, xs)
    position = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    irradiance = np.zeros_like(position)
    irradiance[len(position) // 2] = 1.0
    source = IrradianceSamples(position, 1.0, irradiance, np.tile([0.0, 0.0, 1.0], (len(position), 1)))
    r = np.arange(3, 40) * cell
    grid = {"resolution": None, "cell_size": cell} if kind == "convolution" else {}
    exitance = _make(kind, source, model_profile("dipole", milk), milk, **grid).exitance(
        np.stack([r, 0 * r, 0 * r], axis=1))
    np.testing.assert_allclose(exitance, model_profile("dipole", milk)(r), rtol=0.02)


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_agrees_with_the_exact_sum_deterministic_and_non_negative(kind):
    """On a sphere, a transport of Eq. 1 agrees with its exact sum (one that follows the object's shape, the volume
    transport, is checked against the sphere's diffusion solution in its own tests)."""
    skin = model_profile("dipole", material("skin1"))
    samples = _sphere()
    points, normals = samples.position[::7], samples.normal[::7]
    exact = make_transport("exact", samples, skin).exitance(points)
    first = _make(kind, samples, skin, material("skin1")).exitance(points, normals)
    again = _make(kind, samples, skin, material("skin1")).exitance(points, normals)
    np.testing.assert_array_equal(first, again)
    assert first.min() >= 0
    if TRANSPORTS[kind].sums_eq1:
        assert np.linalg.norm(first - exact) / np.linalg.norm(exact) < 0.03


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_relit_equals_a_transport_built_for_the_new_irradiance(kind):
    """Eq. 1 is linear in E: a transport relit with other irradiance at the same samples (what it may keep of their
    places) answers as one built for it, and the original is left as it was."""
    skin = model_profile("dipole", material("skin1"))
    samples = _sphere()
    points = samples.position[::7]
    other = samples.irradiance * np.linspace(0.2, 2.0, len(samples))[:, None] + [0.0, 0.1, 0.3]
    first = _make(kind, samples, skin, material("skin1"))
    before = first.exitance(points)
    relit = first.relit(other).exitance(points)
    fresh = _make(kind, IrradianceSamples(samples.position, samples.area, other, samples.normal), skin,
                  material("skin1"))
    np.testing.assert_allclose(relit, fresh.exitance(points), rtol=1e-6, atol=1e-9 * np.abs(before).max())
    np.testing.assert_array_equal(first.exitance(points), before)


@pytest.mark.parametrize("kind", KINDS)
def test_unknown_and_bad_parameters_fail_in_one_line(kind):
    skin = model_profile("dipole", material("skin1"))
    with pytest.raises(ConvsssError, match=f"the {kind} transport has no parameter 'bogus'"):
        make_transport(kind, _sphere(100), skin, FRAME, bogus=1)
    for p in TRANSPORTS[kind].parameters:
        bad = "nonsense" if p.kind is not str else 3.5
        with pytest.raises(ConvsssError, match=f"{p.name}=") as info:
            make_transport(kind, _sphere(100), skin, FRAME, **{p.name: bad})
        assert "\n" not in str(info.value)


@pytest.mark.parametrize("kind", KINDS)
def test_the_sample_area_is_the_profile_s_unless_the_transport_sums_it_otherwise(kind):
    """The plan sizes the samples by ``sample_area``: a positive area, the profile's own effective area where the
    profile is resolved (a footprint much finer than its core), never smaller than it for a coarse footprint."""
    cls = TRANSPORTS[kind]
    skin = model_profile("dipole", material("skin1"))
    own = float(np.min(skin.effective_area()))
    fine = {"cell_size": 0.01} if cls.accepts("cell_size") else {}
    coarse = {"cell_size": 5.0} if cls.accepts("cell_size") else {}
    assert cls.sample_area(skin, fine) == pytest.approx(own)
    assert cls.sample_area(skin, coarse) >= own > 0


@pytest.mark.parametrize("kind", KINDS)
def test_planned_bytes_are_known_before_the_samples_and_bound_what_is_built(kind):
    """A plan (:mod:`convsss.pipeline.plan`) asks a transport what it will hold from the samples' bounds alone, before
    any sample exists: a number >= 0, at least the structures the built transport holds (the multiscale far-field
    spectra, the convolution's layers) and not many times more."""
    cls = TRANSPORTS[kind]
    skin = model_profile("dipole", material("skin1"))
    sphere = _sphere(radius=3.0)
    view = FRAME.to_view(sphere.position)
    bounds = np.array([view.min(axis=0), view.max(axis=0)])
    params = {**ACCURATE.get(kind, {}), **({"cell_size": 0.05} if cls.accepts("cell_size") else {})}
    if kind == "convolution":
        params.pop("resolution")
    planned = cls.planned_bytes(bounds, skin, len(sphere), params, material("skin1"))
    assert isinstance(planned, int) and planned >= 0
    assert cls.layer_cell(0.2, {}) == 0.2 or kind == "convolution"
    built = make_transport(kind, sphere, skin, FRAME, material("skin1"), **params)
    if kind == "multiscale":
        from convsss.transport.multiscale import far_bytes

        assert far_bytes(built.fft_shape) <= planned <= 1.2 * far_bytes(built.fft_shape) + 2**20
    if kind == "convolution":
        assert planned == built.memory_bytes
        assert cls.layer_cell(0.2, {"downsample": 0.5}) == 0.4

"""The conformance suite of the program-kind contract (:class:`ftsweep.testing.KindTests`,
zarr's ``StoreTests`` pattern) run for every kind of this package: one subclass per registered
kind (and per spiral rule and layered wrapper), each naming a one-case sweep on the tests'
catalog. Adding a kind adds one subclass here."""

from __future__ import annotations

from support.kinds import KindTests

from ftsweep import registry


class TestRing(KindTests):
    kind = "ring"
    suffix = ".h"
    sweep = "surface: small_sine\nlayout: ring\naxes: {points: [15000], aspect: [4.0]}\n"


class TestMesh(KindTests):
    kind = "mesh"
    suffix = ".h"
    sweep = "surface: small_lens\nlayout: mesh\naxes: {points: [12000], aspect: [1.0]}\n"


class TestLayeredTable(KindTests):
    kind = "ring"
    suffix = ".h"
    sweep = "surface: small_sine\nlayout: ring\nmachine: short-fts\naxes: {points: [15000], aspect: [4.0]}\n"


class TestSpiralAngle(KindTests):
    kind = "spiral"
    sweep = "surface: small_sine\nlayout: spiral\naxes: {points_per_rev: [60]}\n"


class TestSpiralArc(KindTests):
    kind = "spiral"
    sweep = "surface: small_sine\nlayout: spiral\naxes: {arc_um: [20.0]}\n"


class TestSpiralChord(KindTests):
    kind = "spiral"
    sweep = "surface: small_sine\nlayout: spiral\naxes: {chord_um: [0.05]}\n"


class TestLayeredSpiral(KindTests):
    kind = "spiral"
    sweep = "surface: small_sine\nlayout: spiral\nmachine: short-fts\naxes: {points_per_rev: [60]}\n"


class TestDPath(KindTests):
    kind = "dpath"
    sweep = (
        "surface: concave_sphere\nlayout: dpath\nmachine: sts-xzc\ncutting: dpath-finish\n"
        "dpath: {transition: optimised}\naxes: {spacing_um: [500.0], points_per_cut: [41]}\n"
    )


class TestDPathPvt(KindTests):
    kind = "dpath"
    sweep = (
        "surface: concave_sphere\nlayout: dpath\nmachine: xzc-pmac-pvt\ncutting: dpath-finish\n"
        "axes: {spacing_um: [500.0], points_per_cut: [41]}\n"
    )


class TestFresnelPvt(KindTests):
    kind = "fresnel"
    sweep = (
        "surface: chebyshev_example\nlayout: fresnel\nmachine: xyzc-pmac-pvt\ncutting: fresnel-finish\n"
        "axes: {facet_height_um: [10.0], points_per_turn: [60], feed_um: [8.0]}\n"
    )


class TestFresnel(KindTests):
    kind = "fresnel"
    sweep = (
        "surface: chebyshev_example\nlayout: fresnel\nmachine: xyzc-nanoform\ncutting: fresnel-finish\n"
        "axes: {facet_height_um: [10.0], points_per_turn: [60], feed_um: [8.0]}\n"
    )


def test_every_registered_kind_has_a_conformance_subclass():
    covered = {cls.kind for cls in KindTests.__subclasses__()}
    assert set(registry.kinds()) <= covered

"""Contact forces in results.h5 and ParaView (force chains): two fixed spheres pressed
into each other by delta and one pressed into a plane by delta_w carry Hertz's normal
forces 4/3 E* sqrt(R*) delta^1.5 (E* = E / (2 (1 - nu^2)) for one material, R* = r / 2
between the spheres and r against the plane), and nothing else touches."""
import math

import numpy as np
import pytest

import bondem
from bondem.analysis.results import Results
from bondem.contacts import ContactSettings
from bondem.io.results import ResultsWriter, rewrite_results
from bondem.io.vtk import export_vtk
from bondem.walls import PlaneWall

R = 1e-3
E, NU = 1e8, 0.3
DELTA, DELTA_WALL = 2e-5, 1e-5


def hertz(r_star, overlap):
    e_star = E / (2.0 * (1.0 - NU ** 2))
    return 4.0 / 3.0 * e_star * math.sqrt(r_star) * overlap ** 1.5


def test_contact_forces_are_saved_cut_on_resume_and_drawn(tmp_path):
    # restitution 1: no dashpot, so the free sphere's small speed adds nothing
    glass = bondem.Material(density=2500.0, young_modulus=E, poisson_ratio=NU,
                            friction=0.3, restitution=1.0)
    position = [[0.0, 0.0, 3 * R], [2 * R - DELTA, 0.0, 3 * R], [6 * R, 0.0, R - DELTA_WALL],
                [0.0, 0.0, 9 * R]]
    # the free sphere a million times denser: it moves by ~1e-7 of DELTA in the test
    heavy = bondem.Material(density=2.5e9, young_modulus=E, poisson_ratio=NU, friction=0.3,
                            restitution=1.0)
    model, state = bondem.make_system(position, R, [glass, heavy], material_index=[0, 1, 0, 0],
                                      fixed=[True, False, True, False])
    sim = bondem.Simulation(model, state, contact=ContactSettings(),
                            walls=[PlaneWall([0, 0, 0], [0, 0, 1], glass)])
    path = tmp_path / "results.h5"
    writer = ResultsWriter(path, sim)
    sim.step(3)
    writer.append(sim)
    sim.step(3)
    writer.append(sim)
    writer.close()
    with Results(path) as results:
        rows = results.contacts(-1)
        first = results.contacts(0)
    pair = np.flatnonzero(rows["j"] >= 0)
    wall = np.flatnonzero(rows["j"] < 0)
    assert pair.size == 1 and wall.size == 1 and rows["i"].size == 2   # sphere 3 is free
    assert {int(rows["i"][pair[0]]), int(rows["j"][pair[0]])} == {0, 1}
    assert int(rows["i"][wall[0]]) == 2 and int(rows["j"][wall[0]]) == -1   # wall 0
    force = first["force"]
    pair = np.flatnonzero(first["j"] >= 0)
    wall = np.flatnonzero(first["j"] < 0)
    assert np.linalg.norm(force[pair[0]]) == pytest.approx(hertz(0.5 * R, DELTA), rel=1e-6)
    assert force[wall[0], 2] == pytest.approx(hertz(R, DELTA_WALL), rel=1e-9)  # pushed up
    # on particle i, away from its partner
    i = int(first["i"][pair[0]])
    j = int(first["j"][pair[0]])
    assert np.dot(force[pair[0]], np.subtract(position[j], position[i])) < 0
    # a resume's cut keeps the first frame's rows only
    rewrite_results(path, n_frames=1)
    with Results(path) as results:
        assert results.n_frames == 1
        assert results.file["contact_rows/i"].shape == (2,)
        np.testing.assert_array_equal(results.contacts(0)["force"], first["force"])
    pvd = export_vtk(path, tmp_path / "vtk")
    text = (tmp_path / "vtk" / "contacts_000000.vtp").read_text(errors="replace")
    assert 'NumberOfLines="2"' in text and "force_magnitude" in text
    assert "contacts_000000.vtp" in pvd.read_text()

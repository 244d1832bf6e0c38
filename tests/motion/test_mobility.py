"""Mobility by the Grübler-Kutzbach count: Kumar, section 5.1, Eqs. (2) and (3) and Examples 1-3."""
import dataclasses

import pytest

import derivations
from derivations.mobility import EXAMPLES, MechanismError, describe, mobility, robot_mechanism


def test_kumar_example_1_serial_planar_arms():
    """Figs. 4 and 5: n = g = 3, every f_i = 1, so M = g = 3."""
    assert mobility(3, ["R", "R", "R"], planar=True) == 3
    assert mobility(3, "RPR", planar=True) == 3
    for name in ("planar_3r", "planar_rpr"):
        assert mobility(**EXAMPLES[name]) == 3


def test_kumar_example_2_slider_crank():
    """Fig. 3: n = 3, g = 4, all f_i = 1, M = 1."""
    assert mobility(3, [1, 1, 1, 1], planar=True) == 1
    crank = describe(**EXAMPLES["slider_crank"])
    assert (crank.n, crank.g, crank.connectivity, crank.mobility) == (3, 4, 4, 1)


def test_kumar_example_3_planar_parallel_manipulator():
    """Fig. 6: n = 7, g = 9, f_i = 1, M = 3 by Eq. (3)."""
    assert mobility(7, "R" * 9, planar=True) == 3
    parallel = describe(**EXAMPLES["planar_parallel"])
    assert (parallel.n, parallel.g, parallel.mobility) == (7, 9, 3)


def test_kumar_stewart_platform():
    """Fig. 7: n = 6 x 3 + 1 = 19, g = 24, sum f_i = 12 + 6 + 6 x 3 = 36, M = 6(19 - 24) + 36 = 6."""
    stewart = describe(**EXAMPLES["stewart_platform"])
    assert (stewart.n, stewart.g, stewart.connectivity, stewart.mobility) == (19, 24, 36, 6)
    assert mobility(19, ["R"] * 12 + ["P"] * 6 + ["S"] * 6) == 6


def test_E12_kumar_equation_labels_are_swapped_in_examples_2_and_stewart():
    """Kumar numbers the spatial count Eq. (2) and the planar one Eq. (3), then uses them the other way round:
    Example 2 says "Since it is a planar mechanism we use Equation (2)", and the Stewart platform
    "According to Equation (3), M = 6(19 - 24) + 36". Taken as labelled, neither gives the printed M."""
    crank, stewart = EXAMPLES["slider_crank"], EXAMPLES["stewart_platform"]
    assert mobility(crank["links"], crank["joints"], planar=False) == -2   # Eq. (2) on the slider-crank: not 1
    assert mobility(crank["links"], crank["joints"], planar=True) == 1     # Eq. (3): Kumar's M = 1
    assert mobility(stewart["links"], [j[0] for j in stewart["joints"]], planar=False) == 6  # Eq. (2): M = 6
    # Eq. (3) applied to the Stewart platform's counts gives 3 (19 - 24) + 36 = 21, not 6; and a planar
    # description of it is refused outright, since it has spherical joints
    counted = describe(**stewart)
    assert dataclasses.replace(counted, planar=True).mobility == 21
    with pytest.raises(MechanismError, match="planar mechanism has only R and P joints"):
        mobility(stewart["links"], stewart["joints"], planar=True)


@pytest.mark.parametrize("name", list(derivations.ROBOTS))
def test_every_registered_robot_has_mobility_equal_to_its_joint_count(models, name):
    """A serial chain has n = g, so M = sum f_i = number of joints (all R or P)."""
    model = models[name]
    mechanism = robot_mechanism(model)
    assert mechanism.mobility == model.n == mechanism.g == mechanism.n
    # Kumar's planar chain: revolute axes normal to the plane, prismatic axes in it
    assert mechanism.planar == name.startswith("planar_")


def test_connectivity_by_type_and_by_number():
    assert mobility(1, ["S"]) == 3 and mobility(1, [3]) == 3
    assert mobility(1, ["H"]) == 1 and mobility(1, ["C"]) == 2 and mobility(1, ["U"]) == 2
    # a four-bar linkage: n = 3, g = 4 in the plane gives 1, in space (the general count) -2
    assert mobility(3, "RRRR", planar=True) == 1 and mobility(3, "RRRR") == -2


@pytest.mark.parametrize("links, joints, planar, message", [
    (2, [("R", 0, 1), ("R", 1, 3)], False, r"joint 2 \(R\): unknown link 3; known links: 0 \(ground\) and 1..2"),
    (["crank", "rod"], [("R", "ground", "crank"), ("R", "crank", "piston")], False,
     r"joint 2 \(R\): unknown link 'piston'"),
    (2, [("R", 0, 1), ("R", 1, 1)], False, r"joint 2 \(R\): joins link '1' to itself"),
    (3, [("R", 0, 1), ("R", 1, 2)], False, r"links \['3'\] are attached to no joint"),
    (2, ["R", ("R", 0, 1)], False, "either every joint names its two links"),
    (2, [("R", 0)], False, r"joint 1: expected \(type, link_a, link_b\)"),
    (2, ["X"], False, r"joint 1: expected a joint type \(R, P, H, C, U, S, E\) or a connectivity"),
    (2, [0], False, "joint 1: connectivity must be an integer from 1 to 5"),
    (2, [3], True, "joint 1: connectivity must be an integer from 1 to 2"),
    (2, "RH", True, "joint 2: a planar mechanism has only R and P joints"),
    (-1, [], False, "number of moving links must be >= 0"),
    (["a", "a"], [], False, "a link name repeats"),
    (["ground"], [], False, "each moving link needs a name"),
    ("three", ["R"], False, "expected the number of moving links or a list of their names"),
    (2, [("R", True, 1)], False, "unknown link True"),
])
def test_bad_descriptions_are_refused_naming_the_joint_or_link(links, joints, planar, message):
    with pytest.raises(MechanismError, match=message):
        mobility(links, joints, planar)

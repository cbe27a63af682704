"""Unit tests of the physical description format: round trips, defaults, every refusal."""

from __future__ import annotations

from dataclasses import replace

from hexacal_msgs_py.models import GOUGH_STEWART, HEXA_SLIDE, MODELS
from hexacal_msgs_py.physical_file import (
    default_physical,
    physical_document,
    physical_file_text,
    PHYSICAL_FORMAT,
    physical_from_text,
    PhysicalDescription,
    PhysicalFileError,
    read_physical_file,
    write_physical_file,
)
import pytest


@pytest.mark.parametrize('model', sorted(MODELS))
def test_default_round_trips_through_a_file(tmp_path, model):
    description = default_physical(model)
    path = write_physical_file(tmp_path / 'physical.yaml', description)
    assert read_physical_file(path) == description
    assert physical_document(description)['format'] == PHYSICAL_FORMAT


def test_shipped_defaults_are_the_realistic_machine():
    hexa = default_physical(HEXA_SLIDE)
    assert hexa.platform_mass == 20.0 and hexa.leg_mass == 2.0 and hexa.link_mass == 1.5
    assert hexa.structure_axial_stiffness == (5.0e7,) * 6
    assert hexa.link_axial_stiffness == 1.0e7
    assert hexa.gravity == (0.0, 0.0, -9.81)
    assert 1e7 <= min(default_physical(GOUGH_STEWART).drive_kp) <= max(hexa.drive_kp) <= 1e8


def test_missing_sections_take_the_model_defaults_and_null_is_rigid():
    text = (
        f'format: {PHYSICAL_FORMAT}\nmodel: gough_stewart\n'
        'platform: {mass: 12}\nlink: {axial_stiffness: null}\n'
        'structure: {axial_stiffness: [1e7, 2e7, 3e7, 4e7, 5e7, 6e7]}\n'
        'drives: {kp: 2.0e7}\n'
    )
    description = physical_from_text(text)
    assert description.platform_mass == 12.0
    assert description.link_axial_stiffness is None
    assert description.structure_axial_stiffness == (1e7, 2e7, 3e7, 4e7, 5e7, 6e7)
    assert description.drive_kp == (2.0e7,) * 6
    assert description.actuator_moving_mass == default_physical(GOUGH_STEWART).actuator_moving_mass
    assert description.made_rigid().rigid and not description.rigid
    assert description.weightless().gravity == (0.0, 0.0, 0.0)
    # Per-actuator values that differ are written as a list and read back.
    assert physical_from_text(physical_file_text(description)) == description


@pytest.mark.parametrize(
    'body, key',
    [
        ('platform: {mass: -1}', 'platform.mass'),
        ('platform: {masse: 1}', 'platform.masse'),
        ('platfrom: {mass: 1}', 'platfrom'),
        ('gravity: [0, 0]', 'gravity'),
        ('legs: {com_fraction: 1.5}', 'legs.com_fraction'),
        ('drives: {kp: [1, 2, 3]}', 'drives.kp'),
        ('drives: {kp: 0}', 'drives.kp'),
        ('drives: {following_error_limit: null}', 'drives.following_error_limit'),
        ('link: {axial_stiffness: -5}', 'link.axial_stiffness'),
        ('released_friction: {coulomb: yes}', 'released_friction.coulomb'),
        ('platform: {inertia: [1, 1, .nan]}', 'platform.inertia'),
        ('payload: 3', 'payload'),
    ],
)
def test_a_bad_value_is_refused_naming_its_key(body, key):
    text = f'format: {PHYSICAL_FORMAT}\nmodel: hexa_slide\n{body}\n'
    with pytest.raises(PhysicalFileError, match=key.replace('.', r'\.')):
        physical_from_text(text, 'machine.yaml')


def test_format_and_model_are_required():
    with pytest.raises(PhysicalFileError, match='format'):
        physical_from_text('model: hexa_slide\n')
    with pytest.raises(PhysicalFileError, match='model'):
        physical_from_text(f'format: {PHYSICAL_FORMAT}\nmodel: delta\n')
    with pytest.raises(PhysicalFileError, match='cannot read'):
        read_physical_file('/nonexistent/physical.yaml')


def test_construction_in_code_is_checked_too():
    with pytest.raises(PhysicalFileError, match='link.mass'):
        replace(default_physical(), link_mass=-1.0)
    assert PhysicalDescription(model=HEXA_SLIDE, platform_mass=5).platform_mass == 5.0

"""
The nodes' actuator-quantity parameters default to the model's unit: rad, N m for cranks.

In the driver's tests: it compares the driver's defaults with the identify package's nodes', and
the driver depends on that package (not the other way round).
"""

from hexacal_driver import parameters as driver
from hexacal_driver.machine import true_machine
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.architectures.actuator_defaults import actuator_default
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.sessions import executor_session
from hexacal_identify.nodes import collector_parameters as collector
from hexacal_identify.nodes import executor_parameters as executor
from hexacal_identify.nodes import identify_parameters as identify
from hexacal_identify.nodes import kinematics_parameters as kinematics
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.parameters_file import save_parameters
import pytest

SLIDERS = ('hexa_slide', 'gough_stewart')
LEVER = architecture('rotary_hexapod').actuator_lever_m
# What each dimension multiplies a slider-sized default by on a crank of LEVER metres.
CRANK_SCALE = {
    'length': 1 / LEVER,
    'speed': 1 / LEVER,
    'force': LEVER,
    'stiffness': LEVER**2,
    'reading': 1.0,
}
# A reading noise or floor is a sensor's figure: X um on a slider, X urad on an encoder.
READING_PARAMETERS = {
    'driver': ('slider_noise_m',),
    'identify': ('noise_slider_m', 'scatter_floor_actuator_m'),
}


def _specs(node):
    specs = {
        'driver': driver.PARAMETERS,
        'executor': executor.PARAMETERS,
        'collector': {name: spec for name, (spec, _) in collector.PARAMETERS.items()},
        'kinematics': kinematics.PARAMETERS,
        'identify': identify.PARAMETERS,
    }
    return specs[node]


def _node_defaults(node, model):
    if node == 'driver':
        return driver.actuator_parameter_defaults(model)
    if node == 'executor':
        defaults, _ = executor_session.model_defaults({}, nominal_set(2, seed=0, model=model))
        return {name: defaults[name] for name in executor_session.ACTUATOR_PARAMETERS}
    if node == 'collector':
        return collector.actuator_parameter_defaults(model)
    return kinematics.actuator_parameter_defaults(model)


TABLES = {
    'driver': driver.ACTUATOR_PARAMETERS,
    'executor': executor_session.ACTUATOR_PARAMETERS,
    'collector': collector.ACTUATOR_PARAMETERS,
    'kinematics': kinematics.ACTUATOR_PARAMETERS,
}


@pytest.mark.parametrize('node', sorted(TABLES))
@pytest.mark.parametrize('model', SLIDERS)
def test_slider_defaults_stay_the_specs(node, model):
    specs = _specs(node)
    defaults = _node_defaults(node, model)
    assert set(defaults) == set(TABLES[node])
    for name, value in defaults.items():
        assert value == specs[name].default, name


@pytest.mark.parametrize('node', sorted(TABLES))
def test_crank_defaults_are_the_same_travel_force_and_stiffness(node):
    specs = _specs(node)
    defaults = _node_defaults(node, 'rotary_hexapod')
    for name, dimension in TABLES[node].items():
        spec = specs[name]
        assert defaults[name] == pytest.approx(spec.default * CRANK_SCALE[dimension]), name
        assert spec.low <= defaults[name] <= spec.high, f'{name} outside its descriptor range'


def test_a_crank_is_not_given_slider_millimetres_as_radians():
    driver_defaults = driver.actuator_parameter_defaults('rotary_hexapod')
    # 0.5 mm of following error at a 0.15 m crank's tip is 3.3 mrad, not 0.5 mrad.
    assert driver_defaults['max_following_error_m'] == pytest.approx(5e-4 / LEVER)
    assert driver_defaults['max_following_error_m'] > 6 * 5e-4
    # 2e4 N/m at the tip is 450 N m/rad; 500 N there is 75 N m.
    assert driver_defaults['servo_stiffness_n_per_m'] == pytest.approx(2e4 * LEVER**2)
    assert driver_defaults['max_force_n'] == pytest.approx(500.0 * LEVER)
    assert driver_defaults['slider_noise_m'] == 1e-5  # 10 urad: an encoder's
    executor_defaults = _node_defaults('executor', 'rotary_hexapod')
    # The executor's guard predicts the driver's servos and stops inside their torque limit.
    stiffness = driver_defaults['servo_stiffness_n_per_m']
    assert executor_defaults['servo_stiffness_n_per_m'] == stiffness
    assert executor_defaults['max_force_n'] < driver_defaults['max_force_n']
    assert executor_defaults['max_actuator_speed_m_s'] == pytest.approx(
        driver_defaults['max_actuator_speed_m_s'] * executor.SETTINGS.max_actuator_speed_m_s / 0.1
    )


def test_the_driver_takes_the_model_from_its_true_machine_file(tmp_path):
    path = tmp_path / 'true.yaml'
    save_parameters(path, architecture('rotary_hexapod').default_parameters().vector,
                    model='rotary_hexapod')
    params, _ = true_machine(str(path), '')
    assert params.model == 'rotary_hexapod'
    defaults = driver.actuator_parameter_defaults(params.model)
    assert defaults['max_following_error_m'] == pytest.approx(5e-4 / LEVER)
    assert kinematics.actuator_parameter_defaults(None) == {
        'max_actuator_speed': kinematics.PARAMETERS['max_actuator_speed'].default
    }


def test_every_parameter_in_an_actuator_unit_has_a_dimension():
    # A parameter whose description gives the unit of actuators that turn is an actuator
    # quantity: it must be in its node's table, or be a reading figure kept as it is.
    for node in ('driver', 'executor', 'collector', 'kinematics', 'identify'):
        named = set(TABLES.get(node, {})) | set(READING_PARAMETERS.get(node, ()))
        for name, spec in _specs(node).items():
            if 'for actuators that turn' in spec.description:
                assert name in named, f'{node}.{name}'
    for node, names in READING_PARAMETERS.items():
        for name in names:
            value = _specs(node)[name].default
            assert actuator_default(architecture('rotary_hexapod'), value, 'reading') == value
    assert set(MODELS) >= set(SLIDERS) | {'rotary_hexapod'}
    with pytest.raises(ValueError, match="'torque'"):
        actuator_default(architecture('rotary_hexapod'), 1.0, 'torque')

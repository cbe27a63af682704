"""The nodes of a system agree on the machine model, so on its calibration store (no DDS)."""

from hexacal_identify.bringup.system import launches, launches_from_arguments
from hexacal_identify.core.architectures import architecture
from hexacal_msgs_py.parameters_file import save_parameters


def _nominal(directory, model):
    path = directory / f'{model}.yaml'
    save_parameters(path, architecture(model).default_parameters().vector, model=model)
    return path


def test_the_kinematics_node_follows_the_store_of_the_nominals_model(tmp_path):
    gough_stewart = _nominal(tmp_path, 'gough_stewart')
    nodes = {
        n.executable: n
        for n in launches_from_arguments({'nominal': str(gough_stewart), 'use_driver': 'false'})
    }
    assert nodes['kinematics'].parameters['model'] == 'gough_stewart'
    assert nodes['identify'].parameters['nominal'] == str(gough_stewart.resolve())
    nodes = {n.executable: n for n in launches(nominal=str(gough_stewart), with_kinematics=True)}
    assert nodes['kinematics'].parameters['model'] == 'gough_stewart'
    nodes = {n.executable: n for n in launches(model='gough_stewart', with_kinematics=True)}
    assert nodes['kinematics'].parameters['model'] == 'gough_stewart'
    hexa_slide = _nominal(tmp_path, 'hexa_slide')
    nodes = {n.executable: n for n in launches(nominal=str(hexa_slide), with_kinematics=True)}
    assert nodes['kinematics'].parameters['model'] == 'hexa_slide'


def test_a_kinematics_parameters_file_names_the_model_itself(tmp_path):
    gough_stewart = _nominal(tmp_path, 'gough_stewart')
    nodes = {
        n.executable: n
        for n in launches(
            nominal=str(gough_stewart),
            with_kinematics=True,
            kinematics_parameters=str(gough_stewart),
        )
    }
    assert 'model' not in nodes['kinematics'].parameters
    assert nodes['kinematics'].parameters['parameters'] == str(gough_stewart.resolve())

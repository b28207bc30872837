"""Every one-stage baseline's model config (CPU and paper size) builds the class it names."""

import pytest
from baseline_data import model_from_config

from baselines import LIST, TMNet


@pytest.mark.parametrize(
    "config, cls",
    [
        ("conf/model/list_tiny.yaml", LIST),
        ("conf/model/tmnet_tiny.yaml", TMNet),
        pytest.param("conf/model/list.yaml", LIST, marks=pytest.mark.slow),
        pytest.param("conf/model/tmnet.yaml", TMNet, marks=pytest.mark.slow),
    ],
)
def test_config_files_build_the_model(config, cls):
    assert type(model_from_config(config)) is cls

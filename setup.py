"""ament_python package ``adcs_sim``: installable by ``colcon build`` and by ``pip install``."""
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = 'adcs_sim'
HERE = Path(__file__).resolve().parent


def runtime_requirements() -> list[str]:
    """The pinned runtime dependencies: requirements.txt is their one source (``pip install -r``
    and ``pip install .`` get the same pins; the ros-* must stay pinned, unpinned they resolve to
    a later ROS distribution)."""
    lines = (HERE / 'requirements.txt').read_text().splitlines()
    return [line.split('#', 1)[0].strip() for line in lines if line.split('#', 1)[0].strip()]


# Node executables: the name is also the node name and the scenario-file section name.
NODES = {
    'dynamics': 'adcs_sim.nodes.dynamics:main',
    'recorder': 'adcs_sim.nodes.recorder:main',
    'fault_injector': 'adcs_sim.nodes.fault_injector:main',
    'pd_controller': 'adcs_controllers.nodes.pd_controller:main',
    'minnorm_controller': 'adcs_controllers.nodes.minnorm_controller:main',
    'gsmn_controller': 'adcs_controllers.nodes.gsmn_controller:main',
    'kt_controller': 'adcs_controllers.nodes.kt_controller:main',
    'zero_momentum_controller': 'adcs_controllers.nodes.zero_momentum_controller:main',
    'snlc_controller': 'adcs_controllers.nodes.snlc_controller:main',
    'snlc_minnorm_controller': 'adcs_controllers.nodes.snlc_minnorm_controller:main',
    'snlc_gsmn_controller': 'adcs_controllers.nodes.snlc_gsmn_controller:main',
    'm2r_controller': 'adcs_controllers.nodes.m2r_controller:main',
    'm2s_controller': 'adcs_controllers.nodes.m2s_controller:main',
    'pointing_a_controller': 'adcs_controllers.nodes.pointing_a_controller:main',
    'pointing_b_controller': 'adcs_controllers.nodes.pointing_b_controller:main',
    'backstepping_controller': 'adcs_controllers.nodes.backstepping_controller:main',
    'mekf_estimator': 'adcs_controllers.nodes.mekf_estimator:main',
    'quest_estimator': 'adcs_controllers.nodes.quest_estimator:main',
}
TOOLS = {
    'adcs-run': 'adcs_sim.app.graph.runner:main',
    'adcs-analyze': 'adcs_sim.app.analysis.analyze:main',
    'adcs-bag-repair': 'adcs_sim.app.analysis.repair:main',
    'adcs-montecarlo': 'adcs_sim.app.campaign.montecarlo:main',
    'adcs-tune-gsmn': 'adcs_sim.app.campaign.tuning:main',
}

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(include=['adcs_core*', 'adcs_msgs_py*', 'adcs_controllers*', 'adcs_sim*']),
    package_data={'adcs_msgs_py': ['fastdds_profile.xml'], 'adcs_sim.nodes': ['recorder_fastdds.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', sorted(glob('config/*.yaml'))),
        ('share/' + PACKAGE + '/config/campaigns', sorted(glob('config/campaigns/*.yaml'))),
    ],
    install_requires=runtime_requirements(),
    zip_safe=True,
    maintainer='adcs_sim developers',
    maintainer_email='adcs-sim@example.org',
    description='Spacecraft ADCS simulation as a ROS 2 Jazzy node graph',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [f'{name} = {target}' for name, target in {**NODES, **TOOLS}.items()],
    },
)

"""ament_python package ``adcs_sim``: installable by ``colcon build`` and by ``pip install``."""
import os
import shutil
import subprocess
import sys
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup
from setuptools.command.build_py import build_py

PACKAGE = 'adcs_sim'
HERE = Path(__file__).resolve().parent


def runtime_requirements() -> list[str]:
    """The pinned runtime dependencies: requirements.txt is their one source (``pip install -r``
    and ``pip install .`` get the same pins; the ros-* must stay pinned, unpinned they resolve to
    a later ROS distribution)."""
    lines = (HERE / 'requirements.txt').read_text().splitlines()
    return [line.split('#', 1)[0].strip() for line in lines if line.split('#', 1)[0].strip()]


class BuildWithKernels(build_py):
    """``build_py``, then every numba kernel compiled into the built copy (``python -m
    adcs_sim.app.batch.kernels``, one line per compilation), so that the wheel carries numba's cache
    and the first run after ``pip install`` compiles nothing (numba checks a cached kernel against the
    hash of its source file, which installing does not change; the cache holds machine code for the
    CPU that built it, another CPU compiles on first use, printing what). The source tree's own cache
    (``make install``) is copied first: then nothing compiles. Not for an editable install (the tree
    itself is imported: ``make install`` compiles there); ``ADCS_BUILD_KERNELS=0`` skips it."""

    def run(self):
        super().run()
        if getattr(self, 'editable_mode', False) or os.environ.get('ADCS_BUILD_KERNELS', '1') == '0':
            return
        build_lib = Path(self.build_lib).resolve()
        for cached in [*HERE.glob('adcs_*/**/__pycache__/*.nbi'), *HERE.glob('adcs_*/**/__pycache__/*.nbc')]:
            target = build_lib / cached.relative_to(HERE)
            if target.parent.parent.is_dir():
                target.parent.mkdir(exist_ok=True)
                shutil.copy2(cached, target)
        path = os.pathsep.join([str(build_lib), *filter(None, [os.environ.get('PYTHONPATH')])])
        subprocess.run([sys.executable, '-m', 'adcs_sim.app.batch.kernels'], env=dict(os.environ, PYTHONPATH=path),
                       cwd=build_lib, check=True)


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
    cmdclass={'build_py': BuildWithKernels},
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

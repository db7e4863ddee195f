"""ament_python packaging: installs the package, its share files and its executables."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'octoroach_model'
# every executable X has octoroach_model.cli.X_main; keep in step with cli.py
EXECUTABLES = ('simulator', 'recorder', 'validator', 'replay', 'simulate', 'validate',
               'diagnose', 'repair', 'convert', 'study', 'plan')

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    # PEP 561: the package is typed (mypy --strict on its core), so a user's mypy checks
    # calls into it instead of treating it as untyped
    package_data={PACKAGE: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
        (f'share/{PACKAGE}/config', glob('config/*.yaml')),     # Table II, params files
        (f'share/{PACKAGE}/launch', glob('launch/*.launch.xml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='octoroach_model developers',
    maintainer_email='octoroach-model@example.org',
    description='Stochastic kinematic model of the OctoRoACH, its probabilistic validation '
                'and a data-driven diagnosis of what it gets wrong.',
    license='BSD-3-Clause',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            f'{name} = {PACKAGE}.cli:{name}_main'
            for name in EXECUTABLES
        ],
    },
)

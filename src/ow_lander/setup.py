from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(
    **generate_distutils_setup(
        packages=[
            "ow_lander",
            "ow_lander.actions",
            "ow_lander.arm_services",
            "ow_lander.execution",
            "ow_lander.mast",
            "ow_lander.operations",
            "ow_lander.planning",
            "ow_lander.telemetry",
        ],
        package_dir={"": "src"},
    )
)

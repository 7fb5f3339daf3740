"""ament_python package `mars_lander`: the simulator, autopilot and tools (see README.md).

Installed two ways: `pip install -e .` into the project venv (done by ./dev), or `colcon build`
on a full ROS 2 install (then `ros2 run mars_lander sim_node`). Python dependencies are pinned in
requirements.txt and declared for rosdep in package.xml, so none are listed here.
"""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "mars_lander"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=["lander_sim*", "lander_autopilot*", "lander_tools*", "lander_ros*", "lander_yaml*"]),
    # py.typed: the packages' annotations are for their users' type checkers too (PEP 561).
    package_data={
        "lander_sim": ["scenes/*.yaml", "py.typed"],
        "lander_autopilot": ["py.typed"],
        "lander_tools": ["live/web/*", "py.typed"],
        "lander_ros": ["py.typed"],
        "lander_yaml": ["py.typed"],
    },
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
        (f"share/{PACKAGE}/scenes", glob("lander_sim/scenes/*.yaml")),
        (f"share/{PACKAGE}/bench", glob("bench/*.py")),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/flights", glob("flights/*.yaml")),
        (f"share/{PACKAGE}/sweeps", glob("sweeps/*.yaml")),
    ],
    # colcon test runs pytest when the package declares it a test dependency (its "test" extra);
    # pytest-xdist lets `./dev test` run the files in parallel (the suite also runs without it).
    extras_require={"test": ["pytest", "pytest-xdist"]},
    zip_safe=False,
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            "lander = lander_tools.cli:main",
            "sim_node = lander_sim.node:main",
            "autopilot_node = lander_autopilot.node:main",
        ],
        # Controller plug-ins: name = module:factory. Registered by lander_autopilot.controllers.
        "mars_lander.controllers": [],
    },
)

"""ament_python / pip install of pascal_calib_ros."""

from glob import glob

from setuptools import find_packages, setup

package_name = "pascal_calib_ros"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
        ("share/" + package_name + "/config/targets", glob("config/targets/*.yaml")),
        ("share/" + package_name + "/launch", glob("launch/*.launch.py")),
    ],
    # pip installs; a ROS install gets these from package.xml through rosdep (rosbags: see README)
    install_requires=["setuptools", "numpy", "scipy", "numba", "opencv-python-headless", "pyyaml", "matplotlib",
                      "rosbags"],
    zip_safe=True,
    maintainer="pascal_calib_ros maintainers",
    maintainer_email="maintainers@pascal-calib.invalid",
    description="Camera calibration from circular targets via circular points and Pascal's theorem",
    license="BSD-3-Clause",
    python_requires=">=3.10",
    entry_points={
        "console_scripts": [
            "pascal-calib = pascal_calib_ros.cli:main",
            "calibration_node = pascal_calib_ros.ros.calibration_node:main",
            "replay_node = pascal_calib_ros.ros.replay_node:main",
            "publisher = pascal_calib_ros.ros.publisher_node:main",
        ],
    },
)

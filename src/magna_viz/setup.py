from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["magna_viz", "magna_viz.replay"], package_dir={"": "src"}))

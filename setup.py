# The campaign's Python package (src/pd_campaign), installed by catkin (catkin_python_setup in
# CMakeLists.txt): after `source catkin_ws/devel/setup.bash`, `import pd_campaign` works from
# anywhere, and the scripts in scripts/ (campaign, campaign_merge, campaign_compare, table2.py,
# ...) import it without touching sys.path.
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=['pd_campaign', 'pd_campaign.sensitivity'],
                                 package_dir={'': 'src'}))

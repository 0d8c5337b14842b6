"""Traffic campaigns: random arrival-traffic scenarios (``mal-traffic``) planned in bulk (``mal-campaign``).

Modules: :mod:`.traffic` generates scenarios; :mod:`.outcome` classifies a planning run into one of
:data:`mal_planner.errors.FAILURE_CLASSES`; :mod:`.child` plans one scenario in its own process;
:mod:`.isolation` starts that process with a time and memory limit; :mod:`.runner` spreads the scenarios
over a Dask cluster; :mod:`.results` is the CSV table; :mod:`.summary` and :mod:`.figures` the report.
No ROS imports.
"""

"""What the two reference engines share, owned by neither: the CPU engine (``viewer.pathtracer``)
and the GPU engine (``viewer.gpupt``) import this package and never each other.

* ``estimator``  ``ReferenceEngine`` (the interface both engines have), ``EstimatorOptions`` and
                 ``check_options``, the estimator's constants (Russian roulette), the mean and
                 variance of a pixel's sums
* ``setup``      ``RenderSetup``: what an engine renders from (geometry, materials, lights,
                 environment, camera, options)
* ``envmap``     the environment light: constant or lat-long map with importance sampling
* ``wavelengths`` the hero-wavelength estimator's 1 nm bins and their CIE weights
* ``cache``      the reference cache: finished references on disk, for either engine
* ``refusals``   what only the CPU engine renders
* ``select``     the engine choice (``cpu`` / ``gpu`` / ``auto``) and ``make_renderer``, which
                 imports the engine it makes only then

No GL at module level here: the CPU engine's workers import ``setup`` and ``envmap``. (Not
``viewer/reference``: ``viewer.reference`` is the Python API's function.)
"""

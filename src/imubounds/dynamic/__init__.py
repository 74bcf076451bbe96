"""The dynamic pipeline (METHOD.md sections 2-4): drive log + aiding sensors -> interval
estimator -> dynamic error margins compared with the stationary noise.

* :mod:`.aiding` -- GPS boxes, compass deviation, geodesy (section 2);
* :mod:`.estimator` -- the interval estimator and margins (sections 3-4);
* :mod:`.scenario` -- a trip simulator with ground truth (3.5).
"""

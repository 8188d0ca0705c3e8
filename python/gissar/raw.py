"""The image functions' plain results: dicts of NumPy arrays, as the compiled core returns them (the form of
gissar 0.1's API), with the same inputs as the xarray-returning functions in `gissar`.

    gissar.raw.simulate(...)          {'image', 'bounces', 'mask', 'layover', 'shadow', 'geometry',
                                       'metadata', 'centre_enu_m', 'options'}
    gissar.raw.simulate_product(...)  {'image', 'bounces', 'mask', 'lon_deg', 'lat_deg', 'height_m',
                                       'real_amplitude', 'zero_doppler_time_s', 'slant_range_m', ...}
"""
from . import _simulate_product_raw as simulate_product  # noqa: F401
from . import _simulate_raw as simulate  # noqa: F401

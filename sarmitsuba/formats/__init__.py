"""Stage 6, standard formats: raw data and images in the files other SAR tools read.

Stage: 6 (core -> scene -> tracing -> signal -> focus -> products -> **formats** -> stacks -> analysis).

Takes: ``RawData`` and ``SarImage`` with their ``RadarParameters`` and ``GeoReference``.

Gives: CPHD 1.1 (raw data, read and written), SICD (complex images, read and written) and
GeoTIFF (ground-plane intensity in UTM), through the all-or-nothing writer of
:mod:`sarmitsuba.core.outputs`.

=======================  ===============================================================
:mod:`.cphd`             ``write_cphd`` / ``read_cphd`` (NGA.STND.0068, via sarkit), TOA or FX domain
:mod:`.cphd_fx`          CPHD's frequency (FX) domain: fast time to frequency and back
:mod:`.cphd_geometry`    CPHD scene reference point and image area (from the scene's box)
:mod:`.sicd`             ``write_sicd`` / ``read_sicd`` (NGA.STND.0024, via sarkit)
:mod:`.sicd_support`     SICD spatial-frequency support, weighting, centre-of-aperture times
:mod:`.sicd_resample`    SICD grid spacings, carrier, resampling, ``DeltaKCOAPoly``
:mod:`.sicd_slant`       SICD slant-plane grid at the SCP, ground image resampled onto it
:mod:`.sicd_radiometry`  SICD radiometric scale factors (RCS, beta, sigma, gamma nought)
:mod:`.sicd_polygons`    SICD image corners, ``ValidData``, ``RadarCollection/Area``
:mod:`.geotiff`          ``write_geotiff`` (rasterio, pyproj)
:mod:`.provenance`       collection start, creation time, metadata without the user's paths
:mod:`.exports`          the formats by name: ``check_formats``, ``write_exports``
=======================  ===============================================================

Physics: (GEO1) local frame to ECEF, (GEO2) CPHD compensation to the scene reference point and
(GEO2') its frequency domain, (GEO3) GeoTIFF and SICD grids, (GEO4) the slant-plane SICD (section
"Geographic reference and standard formats"), (K3) SICD radiometric scale factors, (K3') the
uniform SICD's weighting taken out.
"""

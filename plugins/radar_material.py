"""``radar`` material and Sionna RT's ``itu-radio-material``: what a surface does to a radar wave.

``radar`` parameters:

.. pluginparameters::

 * - material
   - string
   - A named ITU-R P.2040 material (``concrete``, ``brick``, ``glass``, ``metal``, ``wood``,
     ``medium_dry_ground``, ...; see :data:`sarmitsuba.scene.materials.ITU_MATERIALS`). Its
     permittivity follows the P.2040 frequency fit; frequencies outside the fit's range
     are an error.
 * - relative_permittivity, conductivity
   - float, -, S/m
   - Explicit complex permittivity eta = eps_r - j sigma / (omega eps_0), instead of ``material``.
 * - model
   - string
   - ``half_space`` (default), ``slab`` (single layer in vacuum, P.2040 eqs. 43/44, needs
     ``thickness``) or ``pec`` (perfect conductor, ``|r| = 1``).
 * - thickness
   - float, m
   - Slab thickness (only with ``model = slab``).
 * - gamma_db
   - float, dB
   - Switches distributed clutter and speckle on: a rough surface of constant gamma,
     sigma0 = gamma cos(theta) (monostatic; docs/physics.md (C)). Absent = smooth (PO only).
 * - rms_height, correlation_length, correlation
   - float, m; float, m; string
   - Switches distributed clutter and speckle on: a randomly rough surface of rms height ``s``,
     correlation length ``l`` and autocorrelation ``exponential`` (default) or ``gaussian``,
     whose sigma nought (HH, VV, HV; monostatic and bistatic) is the I2EM's for the material's
     permittivity, geometric optics beyond ``k s = 3`` (docs/physics.md (RS1)-(RS6)). The
     specular reflection is scaled by ``exp(-2 (k s cos theta)^2)``. Not with ``gamma_db``.
 * - cross_pol_db
   - float, dB
   - Polarimetric runs only (``polarization`` ``HV``, ``VH`` or ``quad``): sigma0 of the
     rough surface's cross-polarised return relative to the mean of its co-polarised ones,
     ``sigma0_HV = q (sigma0_HH + sigma0_VV) / 2`` with ``q = 10^(cross_pol_db / 10)``,
     uncorrelated with them (docs/physics.md (P7)). Default -15 dB.
 * - color
   - rgb
   - Colour for optical previews only.

``itu-radio-material`` (Sionna RT 2.x scenes, loaded unchanged): ``type`` (ITU name),
``thickness`` (default 0.1 m, as in Sionna), so the model is the single-layer **slab**, as
Sionna computes it. A non-zero ``scattering_coefficient`` S switches distributed clutter on,
with Sionna's energy split: the specular reflection is scaled by sqrt(1 - S^2) and a
Lambertian backscatter ``sigma0 = 4 S^2 |r|^2 cos^2(theta)`` is added (docs/physics.md (C)).
``xpd_coefficient`` K (default 0, as in Sionna), the fraction of the diffusely scattered power
that is cross-polarised, sets the clutter's cross-polarised level of polarimetric runs:
``q = K / (1 - K)`` (docs/physics.md (P7); K < 1). The scattering-pattern attributes are read
and kept in :attr:`RadarMaterial.ignored` (Lambertian pattern).

For optical renders (``mi.render``) the material behaves as a diffuse BSDF of its colour.
"""
from __future__ import annotations

import math

import mitsuba as mi

from sarmitsuba.scene import materials
from sarmitsuba.scene.fresnel import MaterialError
from sarmitsuba.scene.roughness import RoughSurface
from sarmitsuba.core.constants import VACUUM_PERMITTIVITY
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.core.valid_ranges import unknown_name

_RADAR_KEYS = ("material", "relative_permittivity", "conductivity", "model", "thickness", "gamma_db", "cross_pol_db",
               "rms_height", "correlation_length", "correlation", "color")
_SURFACE_KEYS = ("rms_height", "correlation_length", "correlation")
#: dB: default cross-polarised level of a rough ``radar`` surface (docs/physics.md (P7)).
DEFAULT_CROSS_POL_DB = -15.0
_ITU_KEYS = ("type", "thickness", "scattering_coefficient", "xpd_coefficient", "color", "reflectance",
             "base_color", "alpha_r", "alpha_i", "lambda_", "scattering_pattern")
_ITU_DEFAULT_THICKNESS = 0.1   # m, Sionna RT's DEFAULT_THICKNESS


class RadarMaterial(mi.BSDF):
    """Radar material (see module docstring). :meth:`material_at` gives the electromagnetic model."""

    def __init__(self, props: mi.Properties, sionna: bool = False) -> None:
        super().__init__(props)
        plugin = "itu-radio-material" if sionna else "radar"
        valid = _ITU_KEYS if sionna else _RADAR_KEYS
        values = {}
        for key in props.keys():
            if key not in valid:
                raise ParameterError(f"{plugin} '{props.id()}': unknown parameter {key!r}; "
                                     f"valid parameters: {', '.join(valid)}")
            values[key] = props[key]
        color = next((values.pop(k) for k in ("color", "reflectance", "base_color") if k in values),
                     (0.6, 0.6, 0.6))
        self.plugin, self.name = plugin, props.id() or plugin
        #: Identity of this BSDF object (material tables key rows by it, not by the name).
        self.id_key = id(self)
        #: (kind, value) of the distributed-clutter model (see MaterialTable.clutter) and the factor
        #: on the specular reflection coefficient: smooth unless :meth:`set_roughness` says otherwise.
        self.clutter, self.specular_factor = (0, 0.0), 1.0
        #: The rough surface's statistics (kind 3 clutter, docs/physics.md (RS1)-(RS6)), or None.
        self.surface = None
        #: A preset's surfaces by role where they differ from ``surface`` (docs/physics.md (RS8)),
        #: and the role of each shape (by Mitsuba shape id) that takes one: :meth:`set_role_surfaces`.
        self.role_surfaces, self.shape_roles, self.role_materials = {}, {}, {}
        if sionna:
            self._spec = dict(material=str(values.pop("type", "concrete")), model="slab",
                              thickness=float(values.pop("thickness", _ITU_DEFAULT_THICKNESS)))
            self.set_roughness(scattering_coefficient=values.pop("scattering_coefficient", 0.0))
            xpd = float(values.pop("xpd_coefficient", 0.0))
            if not 0.0 <= xpd < 1.0:
                raise ParameterError(f"{plugin} '{self.name}': xpd_coefficient = {xpd} is outside the valid "
                                     "range [0, 1) (the fraction of scattered power that is cross-polarised)")
            #: sigma0_HV / mean co-polarised sigma0 of the clutter, docs/physics.md (P7).
            self.cross_pol = xpd / (1.0 - xpd)
            #: Parameters read but not modelled (the scattering pattern: Lambertian here).
            self.ignored = values
        else:
            self.ignored = {}
            self.set_roughness(gamma_db=values.pop("gamma_db", None))
            surface = {k: values.pop(k) for k in _SURFACE_KEYS if k in values}
            if surface:
                if self.clutter[0]:
                    raise ParameterError(f"radar '{self.name}': give gamma_db or rms_height/correlation_length, "
                                         "not both (two models of one rough surface)")
                self.set_surface(_surface(self.name, surface))
            cross_db = float(values.pop("cross_pol_db", DEFAULT_CROSS_POL_DB))
            if not math.isfinite(cross_db):
                raise ParameterError(f"radar '{self.name}': cross_pol_db = {cross_db} must be finite (dB)")
            self.cross_pol = 10.0 ** (cross_db / 10.0)
            self._spec = _radar_spec(self.name, values)
        _check_spec(plugin, self.name, **self._spec)
        # The optical BSDF is built on first optical use, not here: plugin constructors run on
        # Mitsuba's parallel scene-loading threads, where a nested mi.load_dict is not safe.
        self._color = [float(c) for c in _as_rgb(color)]
        self._optical_bsdf = None
        self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
        self.m_components = [self.m_flags]

    @property
    def _optical(self):
        """The diffuse BSDF of the material's colour, for optical previews (created lazily)."""
        if self._optical_bsdf is None:
            self._optical_bsdf = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": self._color}})
        return self._optical_bsdf

    def set_roughness(self, gamma_db: float | None = None, scattering_coefficient: float | None = None) -> None:
        """Set the distributed-clutter model (docs/physics.md (C)), on loading and after it (the
        CLI's ``--material-set``): constant gamma ``gamma_db`` [dB], or Sionna's Lambertian
        ``scattering_coefficient`` S in [0, 1] (0: smooth). A parameter left None changes nothing.

        Raises
        ------
        ParameterError
            ``gamma_db`` not finite, or S outside [0, 1].
        """
        label = f"{self.plugin} '{self.name}'"
        if gamma_db is not None:
            if not math.isfinite(float(gamma_db)):
                raise ParameterError(f"{label}: gamma_db = {gamma_db} must be finite")
            self.clutter, self.specular_factor = (1, 10.0 ** (float(gamma_db) / 10.0)), 1.0
            self.surface, self.role_surfaces, self.shape_roles = None, {}, {}
        if scattering_coefficient is not None:
            s = float(scattering_coefficient)
            if not 0.0 <= s <= 1.0:
                raise ParameterError(f"{label}: scattering_coefficient = {s} is outside the valid range [0, 1]")
            self.clutter = (2, 4.0 * s**2) if s > 0 else (0, 0.0)
            self.specular_factor = math.sqrt(1.0 - s**2)
            self.surface, self.role_surfaces, self.shape_roles = None, {}, {}

    @property
    def itu_name(self) -> str | None:
        """The ITU-R P.2040 class of the material (``concrete``, ...), or None (explicit or PEC)."""
        return self._spec.get("material")

    def set_surface(self, surface) -> None:
        """Make the material a randomly rough surface of ``surface``'s statistics
        (:class:`sarmitsuba.scene.roughness.RoughSurface`; None: smooth), whose sigma nought is the
        I2EM's (docs/physics.md (RS1)-(RS6)); replaces any other clutter model."""
        self.surface, self.role_surfaces, self.shape_roles = surface, {}, {}
        self.clutter, self.specular_factor = ((3, 1.0) if surface is not None else (0, 0.0)), 1.0

    def set_role_surfaces(self, surfaces: dict, shape_roles: dict, role_materials: dict | None = None) -> None:
        """Give the shapes of some roles another surface than :attr:`surface` (a preset's rules,
        docs/physics.md (RS8)): ``surfaces`` maps a role to its
        :class:`~sarmitsuba.scene.roughness.RoughSurface` (None: smooth), ``shape_roles`` a
        Mitsuba shape id to its role (shapes not in it keep :attr:`surface`), ``role_materials`` a
        role to the ITU class whose permittivity its shapes take (absent: the material's own)."""
        self.role_surfaces = dict(surfaces)
        self.shape_roles = {int(k): r for k, r in shape_roles.items() if r in self.role_surfaces}
        self.role_materials = {r: m for r, m in (role_materials or {}).items() if m is not None}

    def role_material_at(self, role: str | None, frequency: float) -> "materials.Material":
        """:meth:`material_at` for the shapes of ``role``: the role's ITU class in this material's
        model (slab or half space) where a preset's rule names one, else the material itself."""
        name = getattr(self, "role_materials", {}).get(role) if role is not None else None
        if name is None or self._spec["model"] == "pec":
            return self.material_at(frequency)
        return materials.Material(f"{self.name} ({role})", materials.itu_permittivity(name, frequency),
                                  self._spec["model"], self._spec["thickness"])

    def role_of(self, shape_id: int) -> str | None:
        """The role whose surface shape ``shape_id`` takes, or None (it takes :attr:`surface`)."""
        return self.shape_roles.get(int(shape_id))

    def material_at(self, frequency: float) -> "materials.Material":
        """The electromagnetic model at ``frequency`` [Hz] (raises MaterialError outside the fit's range)."""
        spec = self._spec
        if spec["model"] == "pec":
            return materials.Material.pec(self.name)
        if spec["material"] is not None:
            eta = materials.itu_permittivity(spec["material"], frequency)
        else:   # eta = eps_r - j sigma / (omega eps_0), ITU-R P.2040 eq. (9b)
            eta = complex(spec["relative_permittivity"],
                          -spec["conductivity"] / (2.0 * math.pi * frequency * VACUUM_PERMITTIVITY))
        return materials.Material(self.name, eta, spec["model"], spec["thickness"])

    # optical behaviour: a diffuse surface of the material's colour
    def sample(self, ctx, si, sample1, sample2, active=True):
        return self._optical.sample(ctx, si, sample1, sample2, active)

    def eval(self, ctx, si, wo, active=True):
        return self._optical.eval(ctx, si, wo, active)

    def pdf(self, ctx, si, wo, active=True):
        return self._optical.pdf(ctx, si, wo, active)

    def eval_pdf(self, ctx, si, wo, active=True):
        return self._optical.eval_pdf(ctx, si, wo, active)

    def traverse(self, callback):
        pass

    def to_string(self):
        return f"RadarMaterial[{self.name}: {self._spec}]"


def _radar_spec(name: str, values: dict) -> dict:
    model = str(values.get("model", "half_space"))
    has_named = "material" in values
    has_explicit = "relative_permittivity" in values or "conductivity" in values
    if has_named and has_explicit:
        raise ParameterError(f"radar '{name}': give either material or relative_permittivity/conductivity, not both")
    if model != "pec" and not (has_named or has_explicit):
        raise ParameterError(f"radar '{name}': needs material (ITU name), relative_permittivity/conductivity "
                             "or model = pec")
    if "thickness" in values and model != "slab":
        raise ParameterError(f"radar '{name}': thickness is only used with model = slab (model is {model!r})")
    return dict(material=str(values["material"]) if has_named else None, model=model,
                relative_permittivity=float(values.get("relative_permittivity", 1.0)) if has_explicit else None,
                conductivity=float(values.get("conductivity", 0.0)) if has_explicit else None,
                thickness=float(values["thickness"]) if "thickness" in values else None)


def _surface(name: str, values: dict):
    if "rms_height" not in values or "correlation_length" not in values:
        raise ParameterError(f"radar '{name}': a rough surface needs both rms_height and correlation_length (m); "
                             f"got {', '.join(sorted(values))}")
    try:
        return RoughSurface(float(values["rms_height"]), float(values["correlation_length"]),
                            str(values.get("correlation", "exponential")))
    except MaterialError as error:
        raise ParameterError(f"radar '{name}': {error}") from None


def _check_spec(plugin: str, name: str, material, model, thickness, **_) -> None:
    if model not in ("half_space", "slab", "pec"):
        raise ParameterError(f"{plugin} '{name}': model = {model!r}; valid: half_space, slab, pec")
    if material is not None and material not in materials.itu_material_names():
        raise ParameterError(f"{plugin} '{name}': {unknown_name('ITU material', material, materials.itu_material_names())}")
    if model == "slab" and not (thickness is not None and thickness > 0):
        raise ParameterError(f"{plugin} '{name}': model = slab needs thickness > 0 m, got {thickness}")


def _as_rgb(color) -> tuple[float, float, float]:
    try:
        return tuple(float(c) for c in color)[:3]
    except TypeError:
        return (float(color),) * 3


mi.register_bsdf("radar", lambda props: RadarMaterial(props))
mi.register_bsdf("itu-radio-material", lambda props: RadarMaterial(props, sionna=True))

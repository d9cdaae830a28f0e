"""What `avsim realism` compares: named render settings (`--settings a,b`, side by side) and the
networks that judge them (`--networks`).

Each is a set of config overrides with the physical reason for it; every value is a stated camera
spec, not a number searched for a detector's score. `baseline` is the default renderer.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Mapping

from avsim.config import SimConfig, with_overrides
from avsim.config_owners import dotted_keys



@dataclass(frozen=True)
class RenderSetting:
    """overrides: config sections to keys, e.g. {"camera": {"supersample": 2}}."""

    name: str
    overrides: Mapping[str, Mapping[str, object]]
    why: str

    def config_overrides(self) -> dict[str, dict[str, object]]:
        """The overrides as fresh nested dicts, as `avsim.config.with_overrides` takes them."""
        return {section: dict(values) for section, values in self.overrides.items()}

    @property
    def keys(self) -> frozenset[str]:
        """The dotted keys this setting sets ("camera.supersample", ...): what a file, a flag or a --set may not
        set beside it, and what tells a folder's runs made under it from others."""
        return dotted_keys(self.overrides)

    def config(self, overrides: Mapping[str, Any] = MappingProxyType({})) -> SimConfig:
        """The default config under this setting, then `overrides` (nested, as a command's `--set` gives them)."""
        return with_overrides(with_overrides(SimConfig(), self.config_overrides()), overrides)

    def describe(self) -> str:
        """"camera.supersample=2, ..." or "defaults"."""
        keys = [f"{section}.{key}={value}" for section, values in self.overrides.items() for key, value in values.items()]
        return ", ".join(keys) or "defaults"


# Networks the benchmark can run: the two trained on COCO's photographs and avsim's own detector.
NETWORKS = {"coco": "COCO CenterNet", "yolo": "YOLOv3-tiny", "detector": "own detector", "nanodet": "NanoDet"}

# A lens MTF50 of 0.33 cycles/px (Nyquist is 0.5): an assumed sharp lens. Its Gaussian PSF has
# sigma = 0.57 px; with the photosite's box (supersampling) the system MTF50 comes to about 0.3.
LENS_MTF50_CYC_PER_PX = 0.33
# JPEG quality of an ISP that stores or streams compressed frames: an assumed high quality.
ISP_JPEG_QUALITY = 90

# Anisotropic texture filtering: the most the GL offers (llvmpipe, and most GPUs), the footprint of a pixel on a
# facade seen at 86 deg from its normal (a 14:1 ellipse).
TEXTURE_ANISOTROPY = 16

# The sun's shadow map: 4096 texels over the +-60 m it covers (avsim/world/scene.py), 2.9 cm a texel,
# about the size of a pixel at 26 m with the study camera.
SHADOW_MAP_PX = 4096

# The setting that changes nothing: the default renders.
BASELINE = "baseline"

_PHOTO = {"supersample": 2, "lens_mtf50_cyc_per_px": LENS_MTF50_CYC_PER_PX, "jpeg_quality": ISP_JPEG_QUALITY}
SETTINGS: Mapping[str, RenderSetting] = MappingProxyType({s.name: s for s in (
    RenderSetting(BASELINE, {}, "the default renderer: one sample per pixel, an ideal lens, no encoding"),
    RenderSetting("msaa4", {"camera": {"offsamples": 4}}, "MuJoCo's 4x multisampling: the renderer's edge anti-aliasing"),
    RenderSetting("ss2", {"camera": {"supersample": 2}}, "a photosite integrates light over its area: 2x2 samples, box mean"),
    RenderSetting("lens", {"camera": {"lens_mtf50_cyc_per_px": LENS_MTF50_CYC_PER_PX}}, "a real lens's blur, MTF50 0.33 cycles/px"),
    RenderSetting("jpeg", {"camera": {"jpeg_quality": ISP_JPEG_QUALITY}}, "the ISP's JPEG encoding at quality 90, after the noise"),
    RenderSetting("photo", {"camera": _PHOTO}, "all three photographic stages: ss2, lens and jpeg"),
    RenderSetting("aniso16", {"camera": {"texture_anisotropy": TEXTURE_ANISOTROPY}},
                  "textures filtered over a pixel's footprint up to 16:1, as a photosite integrates a surface seen edge-on"),
    RenderSetting("textured", {"scenario": {"materials": "textured"}},
                  "surfaces with procedural texture at the scale a camera resolves (asphalt, grass, leaves, facades)"),
    RenderSetting("automotive_1080p", {"camera": {"preset": "automotive_1080p"}},
                  "a modern automotive front camera: 1920x1080 at 55 deg horizontal field of view (f 1844 px against 896)"),
    RenderSetting("textured_aniso16", {"scenario": {"materials": "textured"}, "camera": {"texture_anisotropy": TEXTURE_ANISOTROPY}},
                  "textured and aniso16 together: the windows of a facade seen edge-on kept apart, not smeared into streaks"),
    RenderSetting("textured_aniso4", {"scenario": {"materials": "textured"}, "camera": {"texture_anisotropy": 4}},
                  "textured_aniso16 at a quarter of the ratio (a footprint's at 76 deg): on a GL that honours the ratio, how much "
                  "its result rests on 16 (llvmpipe of Mesa 22.3 draws the same pixels at 4 as at 16)"),
    RenderSetting("textured_ss2", {"scenario": {"materials": "textured"}, "camera": {"supersample": 2}},
                  "textured with each photosite's area integrated by 2x2 samples: trilinear's blur across a grazing footprint halved"),
    RenderSetting("textured_ss4", {"scenario": {"materials": "textured"}, "camera": {"supersample": 4}},
                  "textured with 4x4 samples a photosite: its footprint integrated by sampling, not by anisotropic filtering"),
    RenderSetting("textured_photo", {"scenario": {"materials": "textured"}, "camera": _PHOTO}, "textured and photo together"),
    RenderSetting("sheeting", {"scenario": {"sign_materials": "sheeting"}},
                  "sign faces in the standard's sheeting colours (23 CFR 655 boxes) on an aluminium blank, galvanised posts"),
    RenderSetting("shadows", {"scenario": {"sun_shadow_map_px": SHADOW_MAP_PX}}, "the sun casts shadows (4096-texel map)"),
    RenderSetting("clusters", {"scenario": {"foliage": "clusters"}},
                  "tree crowns of leaf clusters with gaps, at a broadleaf crown's optical porosity (0.19), not solid ellipsoids"),
    RenderSetting("daylight_sky", {"scenario": {"sky": "daylight"}},
                  "a clear sky that follows the sun (Preetham et al. 1999, turbidity 3), not a fixed gradient"),
    RenderSetting("hazy_sky", {"scenario": {"sky": "daylight", "sky_turbidity": 6.0}},
                  "the daylight sky at turbidity 6, a hazy day: whiter near the horizon"),
    RenderSetting("gradient_sky_minus1ev", {"scenario": {"sky_exposure_ev": -1.0}},
                  "the default gradient sky one stop darker: its level against the scene is a choice the renderer leaves open"),
    RenderSetting("gradient_sky_plus1ev", {"scenario": {"sky_exposure_ev": 1.0}}, "the default gradient sky one stop brighter"),
    RenderSetting("daylight_sky_minus1ev", {"scenario": {"sky": "daylight", "sky_exposure_ev": -1.0}},
                  "the daylight sky one stop darker: its brightness against the scene is a choice the renderer leaves open"),
    RenderSetting("daylight_sky_plus1ev", {"scenario": {"sky": "daylight", "sky_exposure_ev": 1.0}},
                  "the daylight sky one stop brighter (more of it clips to white)"),
    RenderSetting("scattered_clouds", {"scenario": {"sky": "daylight", "cloud_oktas": 4}},
                  "fair-weather cumulus over half the daylight sky (4 oktas), lit as seen from below"),
    RenderSetting("broken_clouds", {"scenario": {"sky": "daylight", "cloud_oktas": 6}},
                  "fair-weather cumulus over three quarters of the daylight sky (6 oktas)"),
    RenderSetting("scattered_clouds_low", {"scenario": {"sky": "daylight", "cloud_oktas": 4, "cloud_base_m": 600.0}},
                  "scattered_clouds with their base at 600 m, as over the sea, not 1500 m: nearer the sign's line of sight"),
    RenderSetting("scattered_clouds_low_clear",
                  {"scenario": {"sky": "daylight", "cloud_oktas": 4, "cloud_base_m": 600.0, "cloud_visibility_km": 80.0}},
                  "scattered_clouds_low in air of 80 km visibility, not 30: the clouds' contrast near the horizon at its highest"),
    RenderSetting("worn_paint", {"scenario": {"road_paint": "worn"}},
                  "road markings worn through to the asphalt, 75 % of their area still painted"),
    RenderSetting("full_scene_no_shadows",
                  {"scenario": {"materials": "textured", "sign_materials": "sheeting", "foliage": "clusters", "sky": "daylight",
                                "road_paint": "worn"}},
                  "every scene setting but shadows (12x a frame's render): textured, sheeting, clusters, daylight sky, worn paint"),
    RenderSetting("window_geometry", {"scenario": {"facade_windows": "geometry"}},
                  "the facades' windows built as geometry in front of a plain wall, not painted in"),
    RenderSetting("textured_window_geometry", {"scenario": {"materials": "textured", "facade_windows": "geometry"}},
                  "textured, with the facades' windows built as geometry: sharp at a grazing view"),
    RenderSetting("textured_window_geometry_msaa4",
                  {"scenario": {"materials": "textured", "facade_windows": "geometry"}, "camera": {"offsamples": 4}},
                  "textured_window_geometry with msaa4: the windows' and the crowns' edges averaged over the pixel, as a "
                  "photosite averages them"),
    RenderSetting("textured_clusters", {"scenario": {"materials": "textured", "foliage": "clusters"}}, "textured and clusters together"),
    RenderSetting("textured_sheeting_shadows",
                  {"scenario": {"materials": "textured", "sign_materials": "sheeting", "sun_shadow_map_px": SHADOW_MAP_PX}},
                  "textured, sheeting and shadows together"),
    RenderSetting("textured_sheeting_clusters_shadows",
                  {"scenario": {"materials": "textured", "sign_materials": "sheeting", "foliage": "clusters",
                                "sun_shadow_map_px": SHADOW_MAP_PX}},
                  "every scene setting together: textured, sheeting, clusters and shadows"),
)})


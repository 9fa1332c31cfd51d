"""Mitsuba 3 reference for tests/environment.rs (an_environment_lit_scene_agrees_with_mitsuba):
the floor and boxes under the sun map that the test writes (`cargo test --release --test
environment` leaves scene.obj and sky.exr in $CARGO_TARGET_TMPDIR/env_mitsuba).

    pip install mitsuba            # 3.x, scalar_rgb on the CPU
    python3 tests/references/mitsuba_env.py DIR

The test samples one sky function into two maps, one per texel convention (see
write_mitsuba_env_scene): this script reads sky_mitsuba.exr, laid out as Mitsuba's envmap
expects (column i at u = i/W, u = 0 facing -z; row j at j/(H-1) from the zenith).
Surfaces are two-sided Lambertian (albedo 0.5); max_depth 2 is direct light only, as the
runner's --max-depth 2.
"""
import os
import sys

import mitsuba as mi

mi.set_variant("scalar_rgb")

WIDTH = HEIGHT = 96
SPP = 4096

if __name__ == "__main__":
    d = sys.argv[1]
    here = os.path.dirname(os.path.abspath(__file__))
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 2},
        "sensor": {
            "type": "perspective",
            "fov": 40,
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 3, 5], target=[0, 0.3, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": WIDTH, "height": HEIGHT, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": SPP},
        },
        "env": {
            "type": "envmap",
            "filename": os.path.join(d, "sky_mitsuba.exr"),
        },
        "scene": {
            "type": "obj",
            "filename": os.path.join(d, "scene.obj"),
            "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}},
        },
    }
    image = mi.render(mi.load_dict(scene))
    mi.util.write_bitmap(os.path.join(here, "env_sun_96.exr"), image)
    print("wrote env_sun_96.exr")

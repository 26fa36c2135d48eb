// A POV-Ray 3.7 marble sphere: the POV-Ray half of docs/coming-from-povray.md's twin
// (marble.scene is the other half; scripts/povray_twin.py renders both).
#version 3.7;
global_settings { assumed_gamma 1.0 ambient_light rgb <1, 1, 1> }
camera { perspective location <0, 0, -9> look_at <0, 0, 0> angle 46 }
background { rgb <0.02, 0.02, 0.03> }
light_source { <-6, 8, -10> rgb <1, 1, 1> }
sphere { <0, 0, 0>, 2
  texture {
    pigment {
      marble
      turbulence 1.0 octaves 6 omega 0.5 lambda 2
      color_map {
        [0.0  rgb <0.85, 0.82, 0.76>]
        [0.6  rgb <0.70, 0.66, 0.60>]
        [0.85 rgb <0.30, 0.26, 0.22>]
        [1.0  rgb <0.08, 0.07, 0.06>]
      }
      scale 0.8
      rotate <0, 0, 30>
    }
    finish { ambient 0.1 diffuse 0.9 specular 0.4 roughness 0.025 }
  }
}

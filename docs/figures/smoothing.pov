// The scene of smoothing.png (smoothing.sh writes the four meshes' .inc files beside it): the
// four surfaces side by side, one orthographic camera, the same light and material.
#version 3.7;
#include "Data.inc"
#include "Below.inc"
#include "Coarse.inc"
#include "Region.inc"
global_settings { assumed_gamma 1.0 }
background { color rgb 1 }
#declare C = (Data_min + Data_max) / 2;
#declare Gap = 230;
#declare Skin = texture {
  pigment { color rgb <0.93, 0.80, 0.68> }
  finish { diffuse 0.75 ambient 0.12 specular 0.15 roughness 0.05 }
}
// Panel k sits at x = k * Gap; the camera looks along +y from the face's side, z pointing down.
#macro Panel(M, K, Label)
  object { M texture { Skin } translate <K * Gap, 0, 0> }
  text {
    ttf "timrom.ttf" Label 0.05, 0
    pigment { color rgb 0.1 }
    finish { ambient 1 diffuse 0 }
    scale 11
    rotate <-90, 0, 0>  // the text's y axis onto −z: upright on screen
    translate C + <K * Gap - strlen(Label) * 2.6, -150, 84>
  }
#end
Panel(Data, 0, "data")
Panel(Below, 1, "--smooth 1 (below the data)")
Panel(Coarse, 2, "--smooth 1 --smooth-from 1")
Panel(Region, 3, "the same in x >= 32 only")
#declare Mid = C + <1.5 * Gap, 0, 14>;  // a little low: the labels
camera {
  orthographic
  location Mid + <0, -600, 0>
  look_at Mid
  sky <0, 0, -1>
  right x * 4 * Gap
  up y * 4 * Gap * 330 / 1600
}
light_source { Mid + <-500, -900, -500> color rgb 1 }
light_source { Mid + <500, -500, 300> color rgb 0.4 shadowless }

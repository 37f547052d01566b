// envcap's lat-long sky (latlong/sky.exr, or a probe's latlong/probe_NNN.exr) as Unity's skybox
// (docs/engines.md, section 5).  Import the .exr as a 2D texture (Texture Shape 2D, no
// compression for HDR), then:
//
//   EnvcapPanoramicSky.Apply(skyTexture, EnvcapPanoramicSky.AxisFlip.X);
//
// Unity's built-in Skybox/Panoramic shader (Skybox-Panoramic.shader, ToRadialCoords) centres its
// image on +X: u = 0.5 - atan2(z, x) / 2 pi, v = 1 - acos(y) / pi.  envcap's lat-long maps are in
// OpenEXR's LatLong convention: the image centre looks along +Z.  Unity is left-handed, so envcap
// geometry comes in with one axis negated; on top of that flip the sky needs a quarter turn
// (the shader's _Rotation turns the sky about +Y, in degrees):
//
//   geometry imported with X negated (x, y, z) -> (-x, y, z):  _Rotation = 90
//   geometry imported with Z negated (x, y, z) -> (x, y, -z):  _Rotation = 270
//
// Derived from the shader's source and checked in numpy against envcap's lat-long convention
// (tests/formats/test_engine_conventions.py reads the two constants from this file); not run in
// Unity here.  Unity's own "Latitude-Longitude Layout (Cylindrical)" cubemap import is closed
// source and its orientation is not verified here.
using UnityEngine;

public static class EnvcapPanoramicSky
{
    public enum AxisFlip { X, Z }

    public const float RotationForXFlip = 90f;
    public const float RotationForZFlip = 270f;

    public static Material Apply(Texture2D latlong, AxisFlip flip, float exposure = 1f)
    {
        var material = new Material(Shader.Find("Skybox/Panoramic"));
        material.SetTexture("_MainTex", latlong);
        material.SetFloat("_Mapping", 1f);        // Latitude Longitude Layout
        material.SetFloat("_ImageType", 0f);      // 360 degrees
        material.SetFloat("_Rotation", flip == AxisFlip.X ? RotationForXFlip : RotationForZFlip);
        material.SetFloat("_Exposure", exposure);
        material.SetColor("_Tint", new Color(0.5f, 0.5f, 0.5f, 0.5f));   // the shader's default: x unity_ColorSpaceDouble ~ 1
        RenderSettings.skybox = material;
        DynamicGI.UpdateEnvironment();
        return material;
    }
}

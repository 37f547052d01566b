# envcap probe set -> Godot 4 textures (docs/engines.md, section 5).
#
# Godot imports .ktx files only as 2D images, so this script reads envcap's probes.ktx2 (an
# RGBA16F cube-map array with the lobe levels as mips) and sky.ktx2 (an RGBA32F cube map) itself
# and builds a CubemapArray and a Cubemap from them:
#
#   var probes := EnvcapProbes.cubemap_array("res://probes/probes.ktx2")   # layer k = probe k
#   var sky := EnvcapProbes.cubemap("res://probes/sky.ktx2")
#   material.set_shader_parameter("envcap_probes", probes)   # uniform samplerCubeArray envcap_probes;
#
# Layout read (KTX 2.0 specification): header fields at bytes 12 (vkFormat), 20 (pixelWidth),
# 32 (layerCount), 36 (faceCount), 40 (levelCount), 44 (supercompressionScheme); the level index
# at byte 80, 24 bytes per level (byteOffset u64, byteLength u64, uncompressedByteLength u64);
# inside a level, layer-major, then face (+X, -X, +Y, -Y, +Z, -Z), then rows from the top.
# Godot's layered textures take one Image per layer-face in the same order
# (ImageTextureLayered.create_from_images: a multiple of 6 images for a CubemapArray), and an
# Image with mipmaps must hold the whole chain down to 1 x 1 (core/io/image.cpp); levels below
# the file's chain are filled with its last level's first texel (envcap's runtime clamps its level
# to the set's chain, so they are never read).
#
# Orientation: envcap's files are in GL's cube-map convention; Godot's RenderingDevice (Vulkan) and
# its Compatibility renderer (GL) select cube faces by the same table, and Godot's world is
# right-handed, Y up, like envcap's: the bytes go in as they are, and a world direction looks a
# probe up unchanged (for a street at an angle: along R d, manifest yaw_deg, as envcap's runtime).
# Not run here (no Godot on envcap's CI): tests/formats/test_engine_conventions.py checks a line-by-line
# Python transcription of cube_images against envcap's reader.
class_name EnvcapProbes
extends RefCounted

const MAGIC := [0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A]
const VK_RGBA16F := 97
const VK_RGBA32F := 109


# One Image per layer-face of a KTX2 cube map or cube-map array, each with its full mip chain.
static func cube_images(path: String) -> Array[Image]:
	var out: Array[Image] = []
	var b := FileAccess.get_file_as_bytes(path)
	if b.size() < 80 or Array(b.slice(0, 12)) != MAGIC:
		push_error("%s: not a KTX2 file" % path)
		return out
	var vk := b.decode_u32(12)
	var n := b.decode_u32(20)
	var layers := maxi(b.decode_u32(32), 1)
	var faces := b.decode_u32(36)
	var levels := maxi(b.decode_u32(40), 1)
	if faces != 6 or b.decode_u32(44) != 0 or (vk != VK_RGBA16F and vk != VK_RGBA32F):
		push_error("%s: expected an uncompressed RGBA16F/RGBA32F cube map (envcap probes.ktx2 or sky.ktx2)" % path)
		return out
	var texel := 8 if vk == VK_RGBA16F else 16
	var fmt := Image.FORMAT_RGBAH if vk == VK_RGBA16F else Image.FORMAT_RGBAF
	var chain := 1
	while (n >> (chain - 1)) > 1:
		chain += 1
	for layer in layers:
		for face in 6:
			var data := PackedByteArray()
			var last := PackedByteArray()
			for k in chain:
				var s := maxi(n >> k, 1)
				if k < levels:
					var size := s * s * texel
					var start := b.decode_u64(80 + 24 * k) + (layer * 6 + face) * size
					last = b.slice(start, start + size)
					data.append_array(last)
				else:
					var fill := last.slice(0, texel)
					for i in s * s:
						data.append_array(fill)
			out.append(Image.create_from_data(n, n, chain > 1, fmt, data))
	return out


# envcap's probes.ktx2 as a CubemapArray (layer k: the probe with EnvcapStreet.pos[k].w == k).
static func cubemap_array(path: String) -> CubemapArray:
	var tex := CubemapArray.new()
	var err := tex.create_from_images(cube_images(path))
	if err != OK:
		push_error("%s: CubemapArray.create_from_images failed (%d)" % [path, err])
	return tex


# envcap's sky.ktx2 (one cube) as a Cubemap.
static func cubemap(path: String) -> Cubemap:
	var tex := Cubemap.new()
	var images := cube_images(path)
	var err := tex.create_from_images(images.slice(0, 6))
	if err != OK:
		push_error("%s: Cubemap.create_from_images failed (%d)" % [path, err])
	return tex

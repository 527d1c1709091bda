// panomap view of a rig: the shader that blends the rig's cameras, and what it reads (panomap.viewer.rig_view).
//
// Every output pixel's ray d (world axes; a floor map's point from each camera's own position) is read through
// each camera's lookup, as the single camera's shader reads its one; the cameras that see it are weighed as
// panomap.rig.blend.feather_weights weighs them, w_k = max(0, d_k - d_max + 2 f) over their sum, each scaled by
// its gain. d_k (output px from the edge of what camera k sees) is the ray's angle inside that edge (rad, which
// every lookup texel carries beside its (u, v)) over its gradient across the screen (dFdx, dFdy): the first-order
// distance to the edge (docs/viewer.md, "A rig").
//
// Used by viewer.js: window.panomapRig.fragment(), .upload(), .setCameras(), .setView().
"use strict";

(() => {
  // Texture units: the source's planes are 1, 3 and 4 (viewer.js); camera k's lookup FIRST_LOOKUP + k.
  const FIRST_LOOKUP = 5;

  function cameraBlock(k) {
    return `
  vec3 colour${k};
  float distance${k};
  {
    vec3 dk = d + shifts[${k}];
    float len = length(dk);
    vec4 lp = lookup_params[${k}];
    vec3 e = dk * frames[${k}];
    vec2 at = lp.z + lp.y * e.xy / (len + lp.x * e.z);
    bool ok = dk.z >= sines[${k}].x * len && dk.z <= sines[${k}].y * len;
    vec3 read = read_lookup(lookup${k}, at, int(lp.w), ok);  // (u, v, the angle inside the edge)
    vec2 uv = read.xy;
    ok = ok && all(greaterThanEqual(uv, vec2(-0.5))) && all(lessThanEqual(uv, placement[${k}].zw - 0.5));
    colour${k} = source_colour(uv + placement[${k}].xy) * gains[${k}];
    float slope = length(vec2(dFdx(read.z), dFdy(read.z)));  // rad per output px (every pixel: no branch)
    distance${k} = ok ? max(read.z / max(slope, 1e-12), 0.0) : -1.0;
  }`;
  }

  // The fragment shader for ``count`` cameras, a way of finding rays (viewer.js's RAYS_LINEAR 0, ANGLES 1,
  // SPHERE 3) and kind of source picture (PLANES 0, 2 or 3), the lookups filtered by the GPU or by hand.
  function fragment(count, rays, planes, linearFloat) {
    const range = (n) => Array.from({ length: n }, (_, k) => k);
    const lookups = range(count).map((k) => `uniform sampler2D lookup${k};`).join("\n");
    const blocks = range(count).map(cameraBlock).join("");
    return `#version 300 es
#define RAYS ${rays}
#define PLANES ${planes}
#define LINEAR_FLOAT ${linearFloat ? 1 : 0}
#define CAMERAS ${count}
precision highp float;
precision highp int;
precision highp sampler2D;
uniform sampler2D source_image; uniform sampler2D plane_u; uniform sampler2D plane_v;
uniform mat3 yuv_to_rgb; uniform vec3 yuv_offset;
uniform vec2 view_origin; uniform vec2 view_size;
uniform vec3 ray_origin; uniform vec3 ray_k; uniform vec3 ray_l;            // RAYS_LINEAR (world axes)
uniform float column_start; uniform float column_step; uniform float row_top; uniform float row_step;  // ANGLES
uniform float table_m; uniform float rho_s; uniform float rho_per_row;
uniform vec3 forward; uniform vec3 right_axis; uniform vec3 down_axis;      // SPHERE (world axes)
uniform vec2 source_scale; uniform vec2 source_offset;
uniform float no_entry;
uniform float feather;             // f (output px)
uniform int outline;
uniform vec3 outline_forward; uniform vec3 outline_right; uniform vec3 outline_down;
uniform float outline_focal; uniform vec2 outline_size;
// Per camera: world rays to its lookup's axes (rows, so d * M), its lookup's pole, scale
// and centre (texture coordinates) and side, the sines of its elevation range, its picture's offset in the
// source and its size, its gains (RGB), and the shift from camera 0's position to its own (a floor map's).
uniform mat3 frames[CAMERAS];
uniform vec4 lookup_params[CAMERAS]; uniform vec2 sines[CAMERAS]; uniform vec4 placement[CAMERAS];
uniform vec3 gains[CAMERAS]; uniform vec3 shifts[CAMERAS];
${lookups}
out vec4 colour;

const float TWO_PI = 6.283185307179586;
const float PI = 3.141592653589793;

vec3 read_lookup(sampler2D lookup, vec2 at, int side, inout bool ok) {
#if LINEAR_FLOAT
  return textureLod(lookup, at, 0.0).xyz;  // (a texel without an entry pulls the pixel far off the picture)
#else
  vec2 texels = at * float(side) - 0.5;
  vec2 cell = floor(texels), t = texels - cell;
  ivec2 texel = clamp(ivec2(cell), ivec2(0), ivec2(side - 2));
  vec3 a00 = texelFetch(lookup, texel, 0).xyz, a10 = texelFetch(lookup, texel + ivec2(1, 0), 0).xyz;
  vec3 a01 = texelFetch(lookup, texel + ivec2(0, 1), 0).xyz, a11 = texelFetch(lookup, texel + ivec2(1, 1), 0).xyz;
  ok = ok && min(min(a00.x, a10.x), min(a01.x, a11.x)) > 0.5 * no_entry;
  return mix(mix(a00, a10, t.x), mix(a01, a11, t.x), t.y);
#endif
}

vec3 source_colour(vec2 uv) {
  vec2 at = uv * source_scale + source_offset;
#if PLANES == 0
  return textureLod(source_image, at, 0.0).rgb;  // (no mipmaps: level 0, as texture() reads it, without its derivatives)
#else
#if PLANES == 2
  vec3 yuv = vec3(texture(source_image, at).r, texture(plane_u, at).rg);
#else
  vec3 yuv = vec3(texture(source_image, at).r, texture(plane_u, at).r, texture(plane_v, at).r);
#endif
  return clamp(yuv_to_rgb * yuv + yuv_offset, 0.0, 1.0);
#endif
}

void main() {
  vec2 at_view = gl_FragCoord.xy - view_origin;
  float k5 = at_view.x, l5 = view_size.y - at_view.y;
#if RAYS == 0
  vec3 d = ray_origin + k5 * ray_k + l5 * ray_l;
#elif RAYS == 1
  float fi = table_m * fract(column_start - k5 * column_step), fj = row_top - l5 * row_step;
  float theta = TWO_PI / table_m * fi, rho = rho_s + rho_per_row * fj;
  vec3 d = vec3(cos(rho) * cos(theta), cos(rho) * sin(theta), sin(rho));
#else
  float a = PI - TWO_PI * k5 / view_size.x, el = 0.5 * PI - PI * l5 / view_size.y;
  vec3 d = cos(el) * cos(a) * forward - cos(el) * sin(a) * right_axis - sin(el) * down_axis;
#endif
${blocks}
  float nearest = ${range(count).map((k) => `distance${k}`).reduce((a, b) => `max(${a}, ${b})`)};
  vec3 sum = vec3(0.0);
  float total = 0.0;
${range(count).map((k) => `  {
    float w = distance${k} >= 0.0 ? max(0.0, distance${k} - nearest + 2.0 * feather) : 0.0;
    sum += w * colour${k};
    total += w;
  }`).join("\n")}
  vec3 rgb = total > 0.0 ? sum / total : vec3(0.0);
#if RAYS == 1
  if (outline == 1) {
    float depth = dot(d, outline_forward);
    vec2 p = vec2(dot(d, outline_right), dot(d, outline_down)) / depth * outline_focal;
    bool inside = depth > 0.0 && abs(p.x) <= 0.5 * outline_size.x && abs(p.y) <= 0.5 * outline_size.y;
    rgb *= inside ? 1.0 : 0.4;
  }
#endif
  colour = vec4(rgb, 1.0);
}`;
  }

  // Each camera's lookup (RGBA32F: u, v, the angle inside its edge; filtered by the GPU where it filters floats).
  function upload(gl, rig, lookups, linearFloat) {
    const most = gl.getParameter(gl.MAX_TEXTURE_SIZE);
    const units = gl.getParameter(gl.MAX_TEXTURE_IMAGE_UNITS);
    if (FIRST_LOOKUP + rig.cameras.length > units) {
      throw new Error(`this GPU reads ${units} textures at once: a rig of ${rig.cameras.length} cameras needs ${FIRST_LOOKUP + rig.cameras.length}`);
    }
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 4);
    rig.cameras.forEach((camera, k) => {
      const side = camera.lookup.side;
      if (side > most) throw new Error(`camera ${camera.name}'s lookup needs ${side} texels a side; this GPU takes at most ${most}`);
      gl.activeTexture(gl.TEXTURE0 + FIRST_LOOKUP + k);
      gl.bindTexture(gl.TEXTURE_2D, gl.createTexture());
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, side, side, 0, gl.RGBA, gl.FLOAT, new Float32Array(lookups[k]));
      const filter = linearFloat ? gl.LINEAR : gl.NEAREST;
      for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, filter);
      for (const p of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T]) gl.texParameteri(gl.TEXTURE_2D, p, gl.CLAMP_TO_EDGE);
    });
  }

  // The uniforms that stay with a program: the lookups' units and each camera's lookup, axes, range and place.
  function setCameras(gl, uniforms, rig, noEntry) {
    const flat = (rows) => rig.cameras.flatMap(rows);
    rig.cameras.forEach((_, k) => gl.uniform1i(uniforms[`lookup${k}`], FIRST_LOOKUP + k));
    gl.uniform1f(uniforms.no_entry, noEntry);
    gl.uniformMatrix3fv(uniforms["frames[0]"], false, flat((c) => c.lookup.frame.flat()));
    gl.uniform4fv(uniforms["lookup_params[0]"], flat((c) => [c.lookup.pole, c.lookup.scale / c.lookup.side, (c.lookup.centre + 0.5) / c.lookup.side, c.lookup.side]));
    gl.uniform2fv(uniforms["sines[0]"], flat((c) => c.sine_range));
    gl.uniform4fv(uniforms["placement[0]"], flat((c) => [...c.offset, ...c.image_size]));
  }

  // The uniforms of one view: the feather (1% of its diagonal, at least 8 px, as the library's), each camera's
  // gains (BGR rows from the server, or one per camera for grey pictures) and shift (a floor map's points are
  // seen from each camera's own position; directions at infinity from every camera alike).
  function setView(gl, uniforms, rig, width, height, gains, surface) {
    gl.uniform1f(uniforms.feather, Math.max(8, 0.01 * Math.hypot(width, height)));
    gl.uniform3fv(uniforms["gains[0]"], rig.cameras.flatMap((_, k) => {
      const g = gains ? gains[k] : [1];
      return g.length >= 3 ? [g[2], g[1], g[0]] : [g[0], g[0], g[0]];
    }));
    const origin = rig.cameras[0].position;
    gl.uniform3fv(uniforms["shifts[0]"], rig.cameras.flatMap((c) => (surface ? c.position.map((x, a) => origin[a] - x) : [0, 0, 0])));
  }

  window.panomapRig = { fragment, upload, setCameras, setView };
})();

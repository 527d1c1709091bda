// panomap view: unwarps the source through the pano-mapping table on the GPU (WebGL2), as the user drags.
//
// Every output pixel: its ray (the view's convention, docs/conventions.md) -> azimuth theta and
// elevation rho -> the table's (u, v), read bilinearly by hand from the entries' float texture
// (azimuth wraps, the last elevation cell continues the line through the last two entries, as
// panomap's own sampling does) -> the source's colour, bilinear, sampled at ((u + 0.5) / width,
// (v + 0.5) / height) (pixel centres at integers). No source: black, as the CLI's views.
//
// API for embedding and tests: window.panomapView (see docs/viewer.md).
"use strict";

(() => {
  const DEG = Math.PI / 180;
  const TWO_PI = 2 * Math.PI;
  const STRIP_HEIGHT_RATIO = 0.25; // the strip's height, of the view's width
  const MODES = ["perspective", "panorama", "floor", "equirect"];
  // The shader's ways to find an output pixel's ray: RAYS_LINEAR (perspective, floor: d affine in the pixel),
  // ANGLES (panorama, an upright equirect: azimuth and elevation affine in the pixel), SPHERE (an equirect
  // turned by a pitch or a roll: the ray from the pixel's angles about the view's axes).
  const RAYS_LINEAR = 0, ANGLES = 1, SPHERE = 3;

  const VERTEX = `#version 300 es
in vec2 corner;
void main() { gl_Position = vec4(corner, 0.0, 1.0); }`;

  // One program per way of finding rays (RAYS): no branch on the kind of view per pixel. Every value that is the
  // same for all pixels is worked out once per view in JavaScript (a software GPU pays for each operation per pixel).
  const FRAGMENT = `
precision highp float;
precision highp int;
precision highp sampler2D;
uniform sampler2D table_entries;  // RGBA32F: texel (c, b*(N+1) + j) = entries (i, j) and (i, j+1), i = b*B + c
uniform sampler2D source_image;   // the omni-image, RGBA8 (or a video frame's Y plane), linear, clamped to its edge
uniform sampler2D plane_u;        // a video frame's U plane (NV12: U and V interleaved)
uniform sampler2D plane_v;        // ... and V plane (I420)
uniform mat3 yuv_to_rgb; uniform vec3 yuv_offset;
uniform vec2 view_origin;         // the viewport's lower-left corner in the canvas (px, GL's y up)
uniform vec2 view_size;           // W, H (px)
// RAYS_LINEAR: the ray d = ray_origin + (k + 0.5) ray_k + (l + 0.5) ray_l, in the lookup's axes where there is
// one (its world Z: ray_z . (1, k + 0.5, l + 0.5)), else in world axes.
uniform vec3 ray_origin; uniform vec3 ray_k; uniform vec3 ray_l; uniform vec3 ray_z;
// ANGLES: table indices fi = M fract(column_start - (k + 0.5) column_step), fj = row_top - (l + 0.5) row_step.
uniform float column_start; uniform float column_step; uniform float row_top; uniform float row_step;
// SPHERE: the view's axes F, R, Dn (the lookup's axes where there is one) and their world Z components.
uniform vec3 forward; uniform vec3 right_axis; uniform vec3 down_axis; uniform vec3 axes_z;
uniform int table_n; uniform float block_width;
uniform vec2 image_low; uniform vec2 image_high;  // the image: -0.5 and size - 0.5 (px)
uniform vec2 source_scale; uniform vec2 source_offset;  // the image's pixel (u, v) -> the source textures' coordinates
uniform float no_entry;
uniform sampler2D lookup_texels;  // RG32F: the lookup's (u, v) at texel (X, Y)
uniform float lookup_pole; uniform float lookup_scale; uniform float lookup_centre;  // (texture coordinates)
uniform int lookup_side;
uniform vec2 sine_range;
uniform float table_m; uniform float rho_s; uniform float rho_per_row;
uniform int outline;              // panorama: dim what the perspective view (outline_*) does not see
uniform vec3 outline_forward; uniform vec3 outline_right; uniform vec3 outline_down;
uniform float outline_focal; uniform vec2 outline_size;
out vec4 colour;

const float TWO_PI = 6.283185307179586;
const float PI = 3.141592653589793;

void main() {
  vec2 at = gl_FragCoord.xy - view_origin;             // (k + 0.5, H - l - 0.5)
  float k5 = at.x, l5 = view_size.y - at.y;            // k + 0.5, l + 0.5
#if RAYS == 1
  float fi = table_m * fract(column_start - k5 * column_step);
  float fj = row_top - l5 * row_step;
#else
#if RAYS == 0
  vec3 d = ray_origin + k5 * ray_k + l5 * ray_l;
  float z = ray_z.x + k5 * ray_z.y + l5 * ray_z.z;
#else
  float a = PI - TWO_PI * k5 / view_size.x, e = 0.5 * PI - PI * l5 / view_size.y;
  float ca = cos(e) * cos(a), sa = cos(e) * sin(a), se = sin(e);
  vec3 d = ca * forward - sa * right_axis - se * down_axis;
  float z = ca * axes_z.x - sa * axes_z.y - se * axes_z.z;
#endif
#if LOOKUP
  // The table's direction lookup (as panomap perspective and floor read it): no trigonometry per pixel.
  float length_d = length(d);
  vec2 at_lookup = lookup_centre + lookup_scale * d.xy / (length_d + lookup_pole * d.z);
  bool seen = z >= sine_range.x * length_d && z <= sine_range.y * length_d;
#if LINEAR_FLOAT
  // The GPU's own bilinear filter (exact float weights on SwiftShader; 1/256 steps on some GPUs, docs/viewer.md).
  // A texel without an entry (NO_ENTRY) pulls the pixel far off the image: no source, as cv2.remap's NaN.
  vec2 uv = texture(lookup_texels, at_lookup).xy;
#else
  vec2 texels = at_lookup * float(lookup_side) - 0.5;
  vec2 cell = floor(texels), t = texels - cell;
  ivec2 texel = clamp(ivec2(cell), ivec2(0), ivec2(lookup_side - 2));
  vec2 a00 = texelFetch(lookup_texels, texel, 0).xy, a10 = texelFetch(lookup_texels, texel + ivec2(1, 0), 0).xy;
  vec2 a01 = texelFetch(lookup_texels, texel + ivec2(0, 1), 0).xy, a11 = texelFetch(lookup_texels, texel + ivec2(1, 1), 0).xy;
  seen = seen && min(min(a00.x, a10.x), min(a01.x, a11.x)) > 0.5 * no_entry;
  vec2 uv = mix(mix(a00, a10, t.x), mix(a01, a11, t.x), t.y);
#endif
#else
  float fi = table_m / TWO_PI * mod(atan(d.y, d.x), TWO_PI);
  float fj = (atan(d.z, length(d.xy)) - rho_s) / rho_per_row;
#endif
#endif
#if RAYS == 1 || !LOOKUP
  // The table itself, bilinear: the cell's two columns, each texel holding an entry and the one a row above.
  float i_floor = min(floor(fi), table_m - 1.0), j_floor = clamp(floor(fj), 0.0, float(table_n));
  float ti = fi - i_floor, tj = fj - j_floor;
#if BLOCKS == 1
  ivec2 texel = ivec2(i_floor, j_floor);
#else
  float block = floor((i_floor + 0.5) / block_width);
  ivec2 texel = ivec2(i_floor - block * block_width, block * float(table_n + 1) + j_floor);
#endif
  vec4 left = texelFetch(table_entries, texel, 0), right = texelFetch(table_entries, texel + ivec2(1, 0), 0);
  bool seen = fj >= 0.0 && fj <= float(table_n) && min(min(left.x, left.z), min(right.x, right.z)) > 0.5 * no_entry;
  vec2 uv = mix(mix(left.xy, right.xy, ti), mix(left.zw, right.zw, ti), tj);
#endif
  seen = seen && all(greaterThanEqual(uv, image_low)) && all(lessThanEqual(uv, image_high));
  vec2 at_source = uv * source_scale + source_offset;
#if PLANES == 0
  vec3 rgb = texture(source_image, at_source).rgb;
#else
#if PLANES == 2
  vec3 yuv = vec3(texture(source_image, at_source).r, texture(plane_u, at_source).rg);
#else
  vec3 yuv = vec3(texture(source_image, at_source).r, texture(plane_u, at_source).r, texture(plane_v, at_source).r);
#endif
  vec3 rgb = clamp(yuv_to_rgb * yuv + yuv_offset, 0.0, 1.0);
#endif
#if RAYS == 1
  if (outline == 1) {
    float theta = TWO_PI / table_m * fi, rho = rho_s + rho_per_row * fj;
    vec3 d = vec3(cos(rho) * cos(theta), cos(rho) * sin(theta), sin(rho));
    float depth = dot(d, outline_forward);
    vec2 p = vec2(dot(d, outline_right), dot(d, outline_down)) / depth * outline_focal;
    bool inside = depth > 0.0 && abs(p.x) <= 0.5 * outline_size.x && abs(p.y) <= 0.5 * outline_size.y;
    rgb *= inside ? 1.0 : 0.4;
  }
#endif
  colour = seen ? vec4(rgb, 1.0) : vec4(0.0, 0.0, 0.0, 1.0);
}`;

  const $ = (id) => document.getElementById(id);
  const state = {
    mode: "perspective",
    yaw: 0, pitch: -30, roll: 0, fov: 90,  // (the camera's optical axis once the table is here: cameraView())
    width: 960, height: 540,
    panoramaStart: 0,       // deg, the panorama's left edge
    floorCentre: null,      // [X, Y] world
    floorHalf: null,        // half the floor map's height (world units)
    strip: true,
  };
  const stats = { views: 0, drawMs: [], sourceFrames: 0, frameTime: null, latencyMs: [], dragToPictureMs: [] };
  let gl = null, uniforms = {}, info = null;
  const programs = {};
  const sourceTextures = {};
  const textureShapes = {};  // the internal format and size each source texture unit holds
  let linearFloat = false, lookupData = null, shownWindow = null, currentFrame = null, serverFrameIndex = 0;
  let sourceReady = false, sourcePlanes = 0, yuvMatrix = null, frameBuffer = null, pendingInput = null;

  function message(text) { $("message").textContent = text || ""; }
  function sourceState(text) { $("source-state").textContent = text || ""; }

  // ------------------------------------------------------------------ geometry (the CLI's conventions)

  function perspectiveAxes(yawDeg, pitchDeg, rollDeg) {
    const psi = yawDeg * DEG, tau = pitchDeg * DEG, omega = rollDeg * DEG;
    const ct = Math.cos(tau), st = Math.sin(tau), cp = Math.cos(psi), sp = Math.sin(psi);
    const forward = [ct * cp, ct * sp, st];
    const right0 = [sp, -cp, 0];
    const down0 = [st * cp, st * sp, -ct];
    const co = Math.cos(omega), so = Math.sin(omega);
    const right = right0.map((r, n) => co * r + so * down0[n]);
    const down = down0.map((r, n) => co * r - so * right0[n]);
    return { forward, right, down };
  }

  function focalPx(width, fovDeg) { return (width / 2) / Math.tan(fovDeg * DEG / 2); }

  function floorDefaults() {
    const [x0, y0, z0] = info.table.camera_position;
    // Round numbers, so that the command line the page gives draws exactly this map.
    state.floorCentre = state.floorCentre || [round(x0, 2), round(y0, 2)];
    state.floorHalf = state.floorHalf || Number(Math.max(Math.abs(z0) * 2, 1e-3).toPrecision(2));
  }

  function floorExtent() {
    floorDefaults();
    const aspect = state.width / state.height;
    const [cx, cy] = state.floorCentre, h = state.floorHalf;
    return [cx - h * aspect, cx + h * aspect, cy - h, cy + h];
  }

  // The perspective view along the camera's optical axis (roll 0), or off it to the middle of what the camera
  // sees where it does not see along it (a mirror camera): as the CLI's perspective view without --yaw and
  // --pitch, field of view 90 deg.
  function cameraView() {
    const [yaw, pitch] = info.table.default_view_deg;
    return { yaw: round(yaw, 4), pitch: round(pitch, 4), roll: 0, fov: 90 };
  }

  function floorProblem() {
    const t = info.table;
    if (!t.camera_height_known) return "the table does not know the camera's height (fit it with --camera-height H)";
    if (t.orientation_deg[1] > 89.9) return "a camera looking up does not see the floor";
    if (t.rho_s >= 0) return "the camera sees nothing below the horizon: no floor";
    if (!(t.camera_position[2] > 0)) return "the camera is not above the floor Z = 0";
    return null;
  }

  // ------------------------------------------------------------------ WebGL

  function compile(type, text) {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, text);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
    return shader;
  }

  // How the shader finds the rays of ``mode``'s pixels (RAYS_LINEAR, ANGLES or SPHERE).
  function raysOf(mode) {
    if (mode === "panorama") return ANGLES;
    if (mode === "equirect") return state.pitch === 0 && state.roll === 0 ? ANGLES : SPHERE;
    return RAYS_LINEAR;
  }

  // A program per way of finding rays and kind of source picture (PLANES 0: RGBA; 2: NV12, Y and interleaved UV;
  // 3: I420, Y, U and V), made on first use with every uniform that does not change from view to view.
  function makeProgram(rays, planes) {
    const program = gl.createProgram();
    gl.attachShader(program, compile(gl.VERTEX_SHADER, VERTEX));
    if (info.rig) return makeRigProgram(program, rays, planes);
    const lookup = rays !== ANGLES && info.table.lookup ? 1 : 0;
    const blocks = Math.ceil(info.table.M / info.table.block_width);
    const defines = `#version 300 es\n#define RAYS ${rays}\n#define LOOKUP ${lookup}\n#define PLANES ${planes}\n#define BLOCKS ${blocks}\n`
      + `#define LINEAR_FLOAT ${linearFloat ? 1 : 0}\n`;
    const locations = link(program, defines + FRAGMENT);
    const t = info.table, size = info.source.size;
    gl.uniform1i(uniforms.table_entries, 0);
    gl.uniform1i(uniforms.source_image, 1);
    gl.uniform1i(uniforms.lookup_texels, 2);
    gl.uniform1i(uniforms.plane_u, 3);
    gl.uniform1i(uniforms.plane_v, 4);
    gl.uniform1f(uniforms.table_m, t.M);
    gl.uniform1i(uniforms.table_n, t.N);
    gl.uniform1f(uniforms.block_width, t.block_width);
    gl.uniform1f(uniforms.rho_s, t.rho_s);
    gl.uniform1f(uniforms.rho_per_row, (t.rho_e - t.rho_s) / t.N);
    gl.uniform1f(uniforms.no_entry, t.no_entry);
    gl.uniform2f(uniforms.image_low, -0.5, -0.5);
    gl.uniform2f(uniforms.image_high, size[0] - 0.5, size[1] - 0.5);
    if (lookup) {
      const side = t.lookup.side;
      gl.uniform1f(uniforms.lookup_pole, t.lookup.pole);
      gl.uniform1f(uniforms.lookup_scale, t.lookup.scale / side);
      gl.uniform1f(uniforms.lookup_centre, (t.lookup.centre + 0.5) / side);
      gl.uniform1i(uniforms.lookup_side, side);
      gl.uniform2f(uniforms.sine_range, Math.sin(t.rho_s), Math.sin(t.rho_e));
    }
    return { program, locations };
  }

  // Links the program with this fragment shader and makes it the one in use: its uniforms' locations by name.
  function link(program, fragment) {
    gl.attachShader(program, compile(gl.FRAGMENT_SHADER, fragment));
    gl.bindAttribLocation(program, 0, "corner");
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
    const locations = {};
    const count = gl.getProgramParameter(program, gl.ACTIVE_UNIFORMS);
    for (let n = 0; n < count; n++) {
      const name = gl.getActiveUniform(program, n).name;
      locations[name] = gl.getUniformLocation(program, name);
    }
    gl.useProgram(program);
    uniforms = locations;
    return locations;
  }

  // A rig's program (viewer_rig.js): every camera's lookup and edge, blended as the library blends them.
  function makeRigProgram(program, rays, planes) {
    const locations = link(program, window.panomapRig.fragment(info.rig.cameras.length, rays, planes, linearFloat));
    const t = info.table;
    gl.uniform1i(uniforms.source_image, 1);
    gl.uniform1i(uniforms.plane_u, 3);
    gl.uniform1i(uniforms.plane_v, 4);
    gl.uniform1f(uniforms.table_m, t.M);
    gl.uniform1f(uniforms.rho_s, t.rho_s);
    gl.uniform1f(uniforms.rho_per_row, (t.rho_e - t.rho_s) / t.N);
    window.panomapRig.setCameras(gl, uniforms, info.rig, t.no_entry);
    return { program, locations };
  }

  function setUpGl(canvas) {
    gl = canvas.getContext("webgl2", { antialias: false, depth: false, stencil: false, preserveDrawingBuffer: false, premultipliedAlpha: false });
    if (!gl) throw new Error("this browser has no WebGL2: the viewer needs it");
    const buffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1, 1, 1]), gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
    gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
    gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
  }

  // Switch to the program of the rays ``rays`` for the source's planes; its uniforms become ``uniforms``.
  function use(rays) {
    const key = `${rays}/${sourcePlanes}`;
    if (!programs[key]) programs[key] = makeProgram(rays, sourcePlanes);
    gl.useProgram(programs[key].program);
    uniforms = programs[key].locations;
    const [x0, y0, w, h] = shownWindow;
    gl.uniform2f(uniforms.source_scale, 1 / w, 1 / h);
    gl.uniform2f(uniforms.source_offset, (0.5 - x0) / w, (0.5 - y0) / h);
    if (sourcePlanes) {
      gl.uniformMatrix3fv(uniforms.yuv_to_rgb, false, yuvMatrix.matrix);
      gl.uniform3fv(uniforms.yuv_offset, yuvMatrix.offset);
    }
  }

  function floatTexture(unit, width, height, bytes) {
    const texture = gl.createTexture();
    gl.activeTexture(unit);
    gl.bindTexture(gl.TEXTURE_2D, texture);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 4);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, width, height, 0, gl.RGBA, gl.FLOAT, new Float32Array(bytes));
    for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
    for (const p of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T]) gl.texParameteri(gl.TEXTURE_2D, p, gl.CLAMP_TO_EDGE);
    return texture;
  }

  function uploadTable(bytes, lookupBytes) {
    const t = info.table;
    const most = gl.getParameter(gl.MAX_TEXTURE_SIZE);
    const side = t.lookup ? t.lookup.side : 0;
    if (Math.max(t.texture_rows, t.texture_width, side) > most) {
      throw new Error(`the table needs a texture of ${Math.max(t.texture_rows, t.texture_width, side)} texels a side; this GPU takes at most ${most} (make a smaller table)`);
    }
    floatTexture(gl.TEXTURE0, t.texture_width, t.texture_rows, bytes);
    if (t.lookup) {
      // Filtered by the GPU where it filters float textures (OES_texture_float_linear), read texel by texel otherwise.
      linearFloat = Boolean(gl.getExtension("OES_texture_float_linear"));
      const texture = gl.createTexture();
      gl.activeTexture(gl.TEXTURE2);
      gl.bindTexture(gl.TEXTURE_2D, texture);
      gl.pixelStorei(gl.UNPACK_ALIGNMENT, 4);
      lookupData = new Float32Array(lookupBytes);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RG32F, side, side, 0, gl.RG, gl.FLOAT, lookupData);
      const filter = linearFloat ? gl.LINEAR : gl.NEAREST;
      for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, filter);
      for (const p of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T]) gl.texParameteri(gl.TEXTURE_2D, p, gl.CLAMP_TO_EDGE);
    }
  }

  // A texture on ``unit`` for the source's pictures, linear and clamped to its edge (made once per unit).
  function sourceTextureOn(unit) {
    gl.activeTexture(gl.TEXTURE0 + unit);
    if (!sourceTextures[unit]) {
      sourceTextures[unit] = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, sourceTextures[unit]);
      for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.LINEAR);
      for (const p of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T]) gl.texParameteri(gl.TEXTURE_2D, p, gl.CLAMP_TO_EDGE);
    }
    gl.bindTexture(gl.TEXTURE_2D, sourceTextures[unit]);
  }

  // The rectangle [x0, y0, width, height] (px, even) of the image that the view reads: the bounding box of the
  // pixels of rays along the view's border (an injective map takes a region's border to its image's border), with
  // a margin; the whole image where the border leaves the table's range, or a panorama (the strip) is drawn.
  function sourceWindow() {
    const [width, height] = info.source.size;
    const whole = [0, 0, width, height];
    const t = info.table;
    if (!lookupData || raysOf(state.mode) !== RAYS_LINEAR || stripHeight() || (state.mode === "floor" && floorProblem())) return whole;
    const rays = linearRays(state.mode, state.width, state.height);
    const sines = [Math.sin(t.rho_s), Math.sin(t.rho_e)];
    let low = [Infinity, Infinity], high = [-Infinity, -Infinity];
    const steps = 32;
    for (let n = 0; n < 4 * steps; n++) {
      const side = Math.floor(n / steps), s = (n % steps) / steps;
      const k = [s, 1, 1 - s, 0][side] * state.width, l = [0, s, 1, 1 - s][side] * state.height;
      const d = [0, 1, 2].map((a) => rays.origin[a] + k * rays.alongK[a] + l * rays.alongL[a]);
      const length = Math.hypot(d[0], d[1], d[2]);
      const sine = d[2] / length;
      if (!(sine >= sines[0] && sine <= sines[1])) return whole;
      const uv = lookupRead(d, length);
      if (!uv || !(uv[0] >= -0.5 && uv[1] >= -0.5 && uv[0] <= width - 0.5 && uv[1] <= height - 0.5)) return whole;
      low = [Math.min(low[0], uv[0]), Math.min(low[1], uv[1])];
      high = [Math.max(high[0], uv[0]), Math.max(high[1], uv[1])];
    }
    const margin = 4 + 0.02 * Math.max(high[0] - low[0], high[1] - low[1]);  // (the border between samples bulges)
    const left = Math.max(0, 2 * Math.floor((low[0] - margin) / 2)), top = Math.max(0, 2 * Math.floor((low[1] - margin) / 2));
    const right = Math.min(width, 2 * Math.ceil((high[0] + margin + 1) / 2)), bottom = Math.min(height, 2 * Math.ceil((high[1] + margin + 1) / 2));
    return [left, top, right - left, bottom - top];
  }

  // Make sure the source textures hold what the view reads (a video frame's window is re-read after a move).
  async function ensureWindow() {
    if (!shownWindow || (!currentFrame && !serverFrameIndex)) return;
    const wanted = sourceWindow(), [x, y, w, h] = shownWindow;
    if (wanted[0] >= x && wanted[1] >= y && wanted[0] + wanted[2] <= x + w && wanted[1] + wanted[3] <= y + h) return;
    try {
      if (currentFrame) await uploadVideoFrame(currentFrame);
      else await serverFrame(serverFrameIndex - 1);  // (the newest frame again, cut to the new window)
    } catch (error) {
      // (the frame was closed by a newer one, or the server went away: the next frame brings its own window)
    }
  }

  // The lookup read on the CPU at ray d (world axes; bilinear), as the shader reads it; null where it has no entry.
  function lookupRead(d, length) {
    const l = info.table.lookup;
    const e = l.frame.map((row) => row[0] * d[0] + row[1] * d[1] + row[2] * d[2]);  // the lookup's axes
    const scale = l.scale / (length + l.pole * e[2]);
    const X = l.centre + scale * e[0], Y = l.centre + scale * e[1];
    const x0 = Math.floor(X), y0 = Math.floor(Y);
    if (!(x0 >= 0 && y0 >= 0 && x0 < l.side - 1 && y0 < l.side - 1)) return null;
    const tx = X - x0, ty = Y - y0;
    const out = [0, 0];
    for (const [dx, dy, w] of [[0, 0, (1 - tx) * (1 - ty)], [1, 0, tx * (1 - ty)], [0, 1, (1 - tx) * ty], [1, 1, tx * ty]]) {
      const at = 2 * ((y0 + dy) * l.side + x0 + dx);
      if (lookupData[at] <= 0.5 * info.table.no_entry) return null;
      out[0] += w * lookupData[at];
      out[1] += w * lookupData[at + 1];
    }
    return out;
  }

  // An image, bitmap or video element: one RGBA picture.
  function uploadSource(element, window_ = null) {
    sourceTextureOn(1);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 4);
    gl.pixelStorei(gl.UNPACK_ROW_LENGTH, 0);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, element);
    textureShapes[1] = null;
    shownWindow = window_ || [0, 0, ...info.source.size];
    sourcePlanes = 0;
    sourceReady = true;
    pictureArrived();
  }

  // The YUV -> RGB matrix and offset of a video frame's colour space (BT.709 or BT.601, limited or full range).
  function yuvConversion(colorSpace) {
    const bt709 = colorSpace && colorSpace.matrix === "bt709";
    const full = Boolean(colorSpace && colorSpace.fullRange);
    const [kr, kb] = bt709 ? [0.2126, 0.0722] : [0.299, 0.114];
    const kg = 1 - kr - kb;
    const ys = full ? 1 : 255 / 219, cs = full ? 1 : 255 / 224;
    const y0 = full ? 0 : 16 / 255;
    // R = Y + 2(1-kr) V, B = Y + 2(1-kb) U, G = (Y - kr R - kb B) / kg; U and V centred on 128 (of 255).
    const rv = 2 * (1 - kr) * cs, bu = 2 * (1 - kb) * cs;
    const gu = -kb * bu / kg, gv = -kr * rv / kg;
    const c0 = 128 / 255;
    // Column-major mat3: columns are Y, U, V.
    const matrix = [ys, ys, ys, 0, gu, bu, rv, gv, 0];
    const offset = [-ys * y0 - rv * c0, -ys * y0 - (gu + gv) * c0, -ys * y0 - bu * c0];
    return { matrix, offset };
  }

  // A decoded video frame (WebCodecs VideoFrame) in NV12 or I420: its planes go up as they are (a fraction of the
  // cost of uploading the video element, which the browser converts to RGBA first); the shader converts.
  async function uploadVideoFrame(frame) {
    const planes = { NV12: 2, I420: 3 }[frame.format];
    if (!planes) {
      uploadSource(frame);
      return;
    }
    // Only the part of the frame the view reads (its window), copied out of the decoder and uploaded.
    const window_ = sourceWindow();
    const rect = { x: window_[0], y: window_[1], width: window_[2], height: window_[3] };
    const width = rect.width, height = rect.height;
    const cw = Math.ceil(width / 2), ch = Math.ceil(height / 2);
    // Planes packed row after row (no row padding): Y, then U and V (I420) or UV (NV12).
    const layout = planes === 2
      ? [{ offset: 0, stride: width }, { offset: width * height, stride: 2 * cw }]
      : [{ offset: 0, stride: width }, { offset: width * height, stride: cw }, { offset: width * height + cw * ch, stride: cw }];
    const size = width * height + 2 * cw * ch;
    if (!frameBuffer || frameBuffer.length < size) frameBuffer = new Uint8Array(size);
    await frame.copyTo(frameBuffer, { rect, layout });
    shownWindow = window_;
    // Textures keep their size while the window does: their storage is reused (texSubImage2D).
    const put = (unit, format, internal, w, h, offset) => {
      sourceTextureOn(unit);
      gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
      const key = `${internal}:${w}x${h}`;
      if (textureShapes[unit] !== key) {
        gl.texImage2D(gl.TEXTURE_2D, 0, internal, w, h, 0, format, gl.UNSIGNED_BYTE, frameBuffer, offset);
        textureShapes[unit] = key;
      } else {
        gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, w, h, format, gl.UNSIGNED_BYTE, frameBuffer, offset);
      }
    };
    put(1, gl.RED, gl.R8, width, height, layout[0].offset);
    if (planes === 2) put(3, gl.RG, gl.RG8, cw, ch, layout[1].offset);
    else {
      put(3, gl.RED, gl.R8, cw, ch, layout[1].offset);
      put(4, gl.RED, gl.R8, cw, ch, layout[2].offset);
    }
    yuvMatrix = yuvConversion(frame.colorSpace);
    sourcePlanes = planes;
    sourceReady = true;
    pictureArrived();
  }

  function stripHeight() { return state.strip && state.mode === "perspective" ? Math.max(16, Math.round(state.width * STRIP_HEIGHT_RATIO)) : 0; }

  // The outline's perspective view (the strip dims what it does not see).
  function setOutlineUniforms() {
    const axes = perspectiveAxes(state.yaw, state.pitch, state.roll);
    gl.uniform3fv(uniforms.outline_forward, axes.forward);
    gl.uniform3fv(uniforms.outline_right, axes.right);
    gl.uniform3fv(uniforms.outline_down, axes.down);
    gl.uniform1f(uniforms.outline_focal, focalPx(state.width, state.fov));
    gl.uniform2f(uniforms.outline_size, state.width, state.height);
  }

  // RAYS_LINEAR: the ray of pixel (k, l) is origin + (k + 0.5) along_k + (l + 0.5) along_l (world axes).
  function linearRays(mode, width, height) {
    if (mode === "floor") {
      const [x0, x1, y0, y1] = floorExtent(), [cx, cy, cz] = info.table.camera_position;
      return { origin: [x0 - cx, y1 - cy, -cz], alongK: [(x1 - x0) / width, 0, 0], alongL: [0, -(y1 - y0) / height, 0] };
    }
    const { forward, right, down } = perspectiveAxes(state.yaw, state.pitch, state.roll);
    const f = focalPx(width, state.fov);
    return {
      origin: [0, 1, 2].map((a) => forward[a] - (0.5 * width / f) * right[a] - (0.5 * height / f) * down[a]),
      alongK: right.map((x) => x / f),
      alongL: down.map((x) => x / f),
    };
  }

  // World vectors in the axes the shader's rays are in: the lookup's where there is one (its frame), else the world's.
  function toRays(vectors) {
    const l = info.table.lookup;
    return l ? vectors.map((v) => l.frame.map((row) => row[0] * v[0] + row[1] * v[1] + row[2] * v[2])) : vectors;
  }

  function drawPart(mode, x, y, width, height, withOutline) {
    gl.viewport(x, y, width, height);
    const rays = raysOf(mode);
    use(rays);
    gl.uniform2f(uniforms.view_origin, x, y);
    gl.uniform2f(uniforms.view_size, width, height);
    const t = info.table, rowsPerRad = t.N / (t.rho_e - t.rho_s);
    if (rays === RAYS_LINEAR) {
      const r = linearRays(mode, width, height);
      const [origin, alongK, alongL] = toRays([r.origin, r.alongK, r.alongL]);
      gl.uniform3fv(uniforms.ray_origin, origin);
      gl.uniform3fv(uniforms.ray_k, alongK);
      gl.uniform3fv(uniforms.ray_l, alongL);
      gl.uniform3f(uniforms.ray_z, r.origin[2], r.alongK[2], r.alongL[2]);
    } else if (rays === SPHERE) {
      const axes = perspectiveAxes(state.yaw, state.pitch, state.roll);
      const [forward, right, down] = toRays([axes.forward, axes.right, axes.down]);
      gl.uniform3fv(uniforms.forward, forward);
      gl.uniform3fv(uniforms.right_axis, right);
      gl.uniform3fv(uniforms.down_axis, down);
      gl.uniform3f(uniforms.axes_z, axes.forward[2], axes.right[2], axes.down[2]);
    } else {
      // ANGLES: azimuth theta_start - 2 pi (k + 0.5) / W, elevation top - (l + 0.5) (top - bottom) / H.
      const equirect = mode === "equirect";
      const start = equirect ? state.yaw * DEG + Math.PI : (withOutline ? state.yaw + 180 : state.panoramaStart) * DEG;
      const [top, bottom] = equirect ? [Math.PI / 2, -Math.PI / 2] : [t.rho_e, t.rho_s];
      gl.uniform1f(uniforms.column_start, start / TWO_PI - Math.floor(start / TWO_PI));
      gl.uniform1f(uniforms.column_step, 1 / width);
      gl.uniform1f(uniforms.row_top, (top - t.rho_s) * rowsPerRad);
      gl.uniform1f(uniforms.row_step, (top - bottom) / height * rowsPerRad);
      gl.uniform1i(uniforms.outline, withOutline ? 1 : 0);
      if (withOutline) setOutlineUniforms();
    }
    if (info.rig) window.panomapRig.setView(gl, uniforms, info.rig, width, height, rigGains.values, mode === "floor");
    gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
  }

  const one = new Uint8Array(4);

  // Draw the view (and the strip below it) now; the GPU has finished when this returns.
  function draw(sync = true) {
    if (!gl || !sourceReady) return false;
    const started = performance.now();
    const canvas = gl.canvas;
    const strip = stripHeight();
    const total = state.height + strip;
    if (canvas.width !== state.width || canvas.height !== total) {
      canvas.width = state.width;
      canvas.height = total;
    }
    if (state.mode === "floor" && floorProblem()) {
      gl.viewport(0, 0, canvas.width, canvas.height);
      gl.clearColor(0, 0, 0, 1);
      gl.clear(gl.COLOR_BUFFER_BIT);
    } else {
      drawPart(state.mode, 0, strip, state.width, state.height, false);
    }
    if (strip) drawPart("panorama", 0, 0, state.width, strip, true);
    if (sync) gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, one); // waits for the GPU: the view is drawn
    stats.views += 1;
    stats.drawMs.push(performance.now() - started);
    if (stats.drawMs.length > 1000) stats.drawMs.shift();
    return true;
  }

  // A rig's gains (panomap.viewer.rig_view.ViewGains): the library's for the view shown, as the view commands find
  // them, asked of the server once the view stays still for GAINS_WAIT_MS (a drag draws with the last view's).
  const GAINS_WAIT_MS = 200;
  const rigGains = { values: null, spec: null, timer: null };

  async function fetchGains(spec) {
    const response = await fetch(`/api/gains?view=${encodeURIComponent(spec)}`);
    const body = await response.json();
    if (!response.ok) throw new Error(body.error || `HTTP ${response.status}`);
    return body.gains;
  }

  function gainsSpec() { return state.mode === "floor" && floorProblem() ? null : commands().spec; }

  // The gains of the view about to be drawn (the API's views, the first view).
  async function ensureGains() {
    const spec = info.rig ? gainsSpec() : null;
    if (spec === null || spec === rigGains.spec) return;
    rigGains.values = await fetchGains(spec);
    rigGains.spec = spec;
  }

  function gainsSoon() {
    if (!info.rig) return;
    clearTimeout(rigGains.timer);
    rigGains.timer = setTimeout(async () => {
      const spec = gainsSpec();
      if (spec === null || spec === rigGains.spec) return;
      try {
        const values = await fetchGains(spec);
        if (gainsSpec() !== spec) return;  // (moved meanwhile: the next wait asks for the new view's)
        rigGains.values = values;
        rigGains.spec = spec;
        requestDraw();
      } catch (error) {
        message(`the gains were not found: ${error.message}`);
      }
    }, GAINS_WAIT_MS);
  }

  let drawQueued = false;
  function requestDraw() {
    if (drawQueued) return;
    drawQueued = true;
    requestAnimationFrame(async () => {
      await ensureWindow();
      drawQueued = false;
      if (draw() && pendingInput !== null) {
        stats.dragToPictureMs.push(performance.now() - pendingInput);
        if (stats.dragToPictureMs.length > 1000) stats.dragToPictureMs.shift();
        pendingInput = null;
      }
      showState();
      gainsSoon();
    });
  }

  function viewPixels() {
    draw();
    const strip = stripHeight();
    const { width, height } = state;
    const data = new Uint8Array(width * height * 4);
    gl.readPixels(0, strip, width, height, gl.RGBA, gl.UNSIGNED_BYTE, data);
    const out = document.createElement("canvas");
    out.width = width;
    out.height = height;
    const context = out.getContext("2d");
    const image = context.createImageData(width, height);
    const row = width * 4;
    for (let y = 0; y < height; y++) image.data.set(data.subarray((height - 1 - y) * row, (height - y) * row), y * row);
    context.putImageData(image, 0, 0);
    return out.toDataURL("image/png");
  }

  // ------------------------------------------------------------------ the view's state, the URL, the commands

  function clampState() {
    state.pitch = Math.max(-90, Math.min(90, state.pitch));
    state.fov = Math.max(1, Math.min(179, state.fov));
    state.yaw = ((state.yaw % 360) + 540) % 360 - 180;
    state.roll = ((state.roll % 360) + 540) % 360 - 180;
    state.width = Math.max(16, Math.min(4096, Math.round(state.width)));
    state.height = Math.max(16, Math.min(4096, Math.round(state.height)));
  }

  const round = (x, digits = 1) => Number(x.toFixed(digits));

  function hashText() {
    const p = state.mode === "perspective"
      ? { view: "perspective", yaw: round(state.yaw, 2), pitch: round(state.pitch, 2), roll: round(state.roll, 2), fov: round(state.fov, 2) }
      : state.mode === "panorama" ? { view: "panorama", start: round(state.panoramaStart, 2) }
      : state.mode === "equirect" ? { view: "equirect", yaw: round(state.yaw, 2), pitch: round(state.pitch, 2), roll: round(state.roll, 2) }
        : { view: "floor", x: round(state.floorCentre[0], 3), y: round(state.floorCentre[1], 3), half: round(state.floorHalf, 3) };
    p.strip = state.strip ? 1 : 0;
    p.width = state.width;
    p.height = state.height;
    return "#" + Object.entries(p).map(([k, v]) => `${k}=${v}`).join("&");
  }

  function readHash() {
    const params = new URLSearchParams(location.hash.slice(1));
    const number = (key) => {
      const v = params.get(key);
      return v !== null && v !== "" && Number.isFinite(Number(v)) ? Number(v) : null;
    };
    if (MODES.includes(params.get("view"))) state.mode = params.get("view");
    for (const key of ["yaw", "pitch", "roll", "fov", "width", "height"]) {
      const v = number(key);
      if (v !== null) state[key] = v;
    }
    if (number("start") !== null) state.panoramaStart = number("start");
    if (number("x") !== null && number("y") !== null) state.floorCentre = [number("x"), number("y")];
    if (number("half") !== null && number("half") > 0) state.floorHalf = number("half");
    if (number("strip") !== null) state.strip = number("strip") !== 0;
    clampState();
  }

  const quote = (text) => (/^[A-Za-z0-9_./:=@%+-]+$/.test(text) ? text : "'" + text.replace(/'/g, "'\\''") + "'");

  function commands() {
    const t = quote(info.table.name), s = info.rig ? info.rig.pictures.map(quote).join(" ") : quote(info.source.name);
    const size = `${state.width}x${state.height}`;
    if (state.mode === "perspective") {
      const [y, p, r, f] = [state.yaw, state.pitch, state.roll, state.fov].map((x) => round(x, 2));
      return {
        command: `panomap perspective ${t} ${s} -o view.png --yaw ${y} --pitch ${p} --roll ${r} --fov ${f} --size ${size}`,
        spec: `perspective:yaw=${y},pitch=${p},roll=${r},fov=${f},size=${size}`,
      };
    }
    if (state.mode === "equirect") {
      const [y, p, r] = [state.yaw, state.pitch, state.roll].map((x) => round(x, 2));
      return {
        command: `panomap equirect ${t} ${s} -o equirect.png --yaw ${y} --pitch ${p} --roll ${r} --size ${size}`,
        spec: `equirect:yaw=${y},pitch=${p},roll=${r},size=${size}`,
      };
    }
    if (state.mode === "panorama") {
      const start = round(state.panoramaStart, 2);
      return { command: `panomap panorama ${t} ${s} -o pano.png --start ${start} --size ${size}`, spec: `panorama:start=${start},size=${size}` };
    }
    const [x0, x1, y0, y1] = floorExtent().map((x) => round(x, 3));
    return {
      command: `panomap floor ${t} ${s} -o floor.png --z 0 --x ${x0} ${x1} --y ${y0} ${y1} --size ${size}`,
      spec: `floor:z=0,x=${x0}:${x1},y=${y0}:${y1},size=${size}`,
    };
  }

  let hashTimer = null;
  function showState() {
    for (const key of ["yaw", "pitch", "roll", "fov", "width", "height"]) {
      const input = $(key);
      if (document.activeElement !== input) input.value = round(state[key], 2);
    }
    $("mode").value = state.mode;
    document.querySelector(".fields").hidden = state.mode !== "perspective" && state.mode !== "equirect";
    $("fov-field").hidden = state.mode !== "perspective";
    $("show-strip").checked = state.strip;
    const c = commands();
    $("command").textContent = c.command;
    $("spec").textContent = c.spec;
    message(state.mode === "floor" ? floorProblem() : "");
    if (hashTimer === null) {
      hashTimer = setTimeout(() => {
        hashTimer = null;
        const text = hashText();
        if (location.hash !== text) history.replaceState(null, "", text);
      }, 150);
    }
  }

  // The fields, the command line and the address follow the view at the next frame (not once per API call).
  let stateQueued = false;
  function showStateSoon() {
    if (stateQueued) return;
    stateQueued = true;
    requestAnimationFrame(() => { stateQueued = false; showState(); });
  }

  function change(update) {
    update();
    clampState();
    requestDraw();
  }

  // ------------------------------------------------------------------ input

  function viewScale() {
    const canvas = gl.canvas;
    return canvas.width / canvas.getBoundingClientRect().width; // canvas px per CSS px
  }

  function setUpInput(canvas) {
    const pointers = new Map();
    let pinchStart = null;
    canvas.addEventListener("pointerdown", (event) => {
      canvas.setPointerCapture(event.pointerId);
      pointers.set(event.pointerId, { x: event.clientX, y: event.clientY });
      canvas.classList.add("dragging");
      const rect = canvas.getBoundingClientRect();
      const y = (event.clientY - rect.top) * viewScale();
      if (pointers.size === 1 && y >= state.height && stripHeight()) {
        // A click on the strip turns the view there.
        const x = (event.clientX - rect.left) * viewScale();
        const strip = stripHeight();
        const t = info.table;
        const theta = state.yaw + 180 - 360 * x / state.width;
        const rho = (t.rho_e - (y - state.height) / strip * (t.rho_e - t.rho_s)) / DEG;
        if (pendingInput === null) pendingInput = event.timeStamp;  // (the oldest input not yet drawn, from its event)
        change(() => { state.yaw = theta; state.pitch = rho; });
        pointers.delete(event.pointerId);
      }
      if (pointers.size === 2) {
        const [a, b] = [...pointers.values()];
        pinchStart = { distance: Math.hypot(a.x - b.x, a.y - b.y), fov: state.fov, half: state.floorHalf };
      }
    });
    canvas.addEventListener("pointermove", (event) => {
      const last = pointers.get(event.pointerId);
      if (!last) return;
      const dx = (event.clientX - last.x) * viewScale(), dy = (event.clientY - last.y) * viewScale();
      pointers.set(event.pointerId, { x: event.clientX, y: event.clientY });
      if (pendingInput === null) pendingInput = event.timeStamp;  // (the oldest input not yet drawn, from its event)
      if (pointers.size === 2 && pinchStart) {
        const [a, b] = [...pointers.values()];
        const ratio = pinchStart.distance / Math.max(1, Math.hypot(a.x - b.x, a.y - b.y));
        change(() => {
          if (state.mode === "floor") state.floorHalf = pinchStart.half * ratio;
          else state.fov = pinchStart.fov * ratio;
        });
        return;
      }
      change(() => {
        if (state.mode === "perspective") {
          const perPixel = 2 * Math.atan(Math.tan(state.fov * DEG / 2) / (state.width / 2)) / DEG; // deg per px at the centre
          state.yaw += dx * perPixel;
          state.pitch += dy * perPixel;
        } else if (state.mode === "panorama") {
          state.panoramaStart += dx * 360 / state.width;
        } else if (state.mode === "equirect") {
          state.yaw += dx * 360 / state.width;
          state.pitch += dy * 180 / state.height;
        } else {
          const perPixel = 2 * state.floorHalf / state.height;
          state.floorCentre = [state.floorCentre[0] - dx * perPixel, state.floorCentre[1] + dy * perPixel];
        }
      });
    });
    const end = (event) => {
      pointers.delete(event.pointerId);
      if (pointers.size < 2) pinchStart = null;
      if (pointers.size === 0) canvas.classList.remove("dragging");
    };
    canvas.addEventListener("pointerup", end);
    canvas.addEventListener("pointercancel", end);
    canvas.addEventListener("wheel", (event) => {
      event.preventDefault();
      if (pendingInput === null) pendingInput = event.timeStamp;  // (the oldest input not yet drawn, from its event)
      const factor = Math.exp(event.deltaY * 0.001);
      change(() => {
        if (state.mode === "floor") { floorDefaults(); state.floorHalf *= factor; } else state.fov *= factor;
      });
    }, { passive: false });
    canvas.addEventListener("keydown", (event) => {
      const steps = { ArrowLeft: ["yaw", 2], ArrowRight: ["yaw", -2], ArrowUp: ["pitch", 2], ArrowDown: ["pitch", -2], q: ["roll", -2], e: ["roll", 2] };
      const key = event.key;
      let update = null;
      if (key in steps) update = () => { state[steps[key][0]] += steps[key][1]; };
      else if (key === "+" || key === "=") update = () => { state.fov /= 1.1; };
      else if (key === "-") update = () => { state.fov *= 1.1; };
      else if (key === "0") update = () => { Object.assign(state, state.mode === "equirect" ? { pitch: 0, roll: 0 } : cameraView()); };
      if (!update) return;
      if (pendingInput === null) pendingInput = event.timeStamp;
      change(update);
      event.preventDefault();
    });
    for (const key of ["yaw", "pitch", "roll", "fov", "width", "height"]) {
      $(key).addEventListener("change", () => {
        const v = Number($(key).value);
        if (Number.isFinite(v)) change(() => { state[key] = v; });
      });
    }
    $("mode").addEventListener("change", () => change(() => {
      state.mode = $("mode").value;
      // The equirect picked here: the whole sphere upright, 2:1, centred on the view's yaw.
      if (state.mode === "equirect") Object.assign(state, { pitch: 0, roll: 0, height: Math.round(state.width / 2) });
    }));
    $("show-strip").addEventListener("change", () => change(() => { state.strip = $("show-strip").checked; }));
    window.addEventListener("hashchange", () => { readHash(); requestDraw(); });
  }

  // ------------------------------------------------------------------ the source

  function loadImage(url) {
    return fetch(url).then((r) => {
      if (!r.ok) throw new Error(`the image did not load (HTTP ${r.status})`);
      return r.blob();
    }).then((blob) => createImageBitmap(blob, { colorSpaceConversion: "none", premultiplyAlpha: "none" }));
  }

  function formatTime(s) {
    if (s === null || s === undefined || !Number.isFinite(s)) return "";
    const m = Math.floor(s / 60);
    return `${m}:${(s - 60 * m).toFixed(2).padStart(5, "0")}`;
  }

  function showTime(seconds) {
    stats.frameTime = seconds;
    const d = info.source.duration_s;
    $("time").textContent = formatTime(seconds) + (d ? " / " + formatTime(d) : "");
    if (d && document.activeElement !== $("seek")) $("seek").value = seconds / d;
  }

  function noteFrame(latencyMs) {
    stats.sourceFrames += 1;
    if (latencyMs !== null) {
      stats.latencyMs.push(latencyMs);
      if (stats.latencyMs.length > 1000) stats.latencyMs.shift();
    }
  }

  // A file the browser plays: frames go up as the video element presents them.
  function playInBrowser() {
    return new Promise((resolve, reject) => {
      const video = $("video");
      let started = false;
      const onFrame = async (now, metadata) => {
        const frame = new VideoFrame(video, { timestamp: Math.round(metadata.mediaTime * 1e6) });
        if (currentFrame) currentFrame.close();
        currentFrame = frame;  // (kept: a view that moves off the uploaded window reads it again)
        try {
          await uploadVideoFrame(frame);
        } catch (error) {
          return video.requestVideoFrameCallback(onFrame);  // (closed meanwhile by a newer frame)
        }
        if (draw(false)) noteFrame(null);
        showTime(metadata.mediaTime);
        if (!started) { started = true; resolve(true); }
        video.requestVideoFrameCallback(onFrame);
      };
      video.addEventListener("error", () => (started ? message("the video stopped playing") : reject(new Error("the browser cannot play it"))), { once: true });
      video.requestVideoFrameCallback(onFrame);
      video.loop = false;
      video.src = "/api/video";
      video.play().catch(reject);
      $("playback").hidden = false;
      $("play").onclick = () => { if (video.paused) video.play(); else video.pause(); };
      video.addEventListener("play", () => { $("play").textContent = "Pause"; });
      video.addEventListener("pause", () => { $("play").textContent = "Play"; });
      $("seek").oninput = () => { if (info.source.duration_s) video.currentTime = Number($("seek").value) * info.source.duration_s; };
    });
  }

  // The newest frame decoded by the server after frame ``after``, cut to the view's window, drawn; the response.
  async function serverFrame(after) {
    const [x, y, w, h] = sourceWindow();
    const response = await fetch(`/api/frame?after=${after}&window=${x},${y},${w},${h}`, { cache: "no-store" });
    if (response.status !== 200) return response;
    const received = performance.now();
    const index = Number(response.headers.get("X-Frame-Index"));
    const age = Number(response.headers.get("X-Frame-Age")) * 1000;
    const window_ = response.headers.get("X-Frame-Window").split(",").map(Number);
    const bitmap = await createImageBitmap(await response.blob(), { colorSpaceConversion: "none", premultiplyAlpha: "none" });
    uploadSource(bitmap, window_);
    bitmap.close();
    serverFrameIndex = Math.max(serverFrameIndex, index);
    if (draw()) noteFrame(age + (performance.now() - received));
    showTime(Number(response.headers.get("X-Frame-Time")));
    return response;
  }

  // Anything else: frames decoded by the server, one request per frame ("the one after the frame I have").
  async function playFromServer() {
    const live = info.source.kind === "live";
    $("playback").hidden = live;
    let paused = false;
    if (!live) {
      $("play").onclick = async () => {
        paused = !paused;
        $("play").textContent = paused ? "Play" : "Pause";
        await post("/api/playback", { paused });
      };
      $("seek").oninput = () => post("/api/playback", { seek_s: Number($("seek").value) * (info.source.duration_s || 0) });
    }
    let lastStatus = 0;
    for (;;) {
      let response;
      try {
        response = await serverFrame(serverFrameIndex);
      } catch (error) {
        sourceState("the viewer's server does not answer (stopped?)");
        await new Promise((r) => setTimeout(r, 1000));
        continue;
      }
      if (response.status === 200) {
        if (stats.sourceFrames === 1 || live) sourceState("");
      } else if (response.status !== 204) {
        const body = await response.json().catch(() => ({}));
        sourceState(body.error || `frames stopped (HTTP ${response.status})`);
        await new Promise((r) => setTimeout(r, 1000));
      }
      if (response.status === 204 || performance.now() - lastStatus > 2000) {
        lastStatus = performance.now();
        const status = await fetch("/api/status").then((r) => r.json()).catch(() => null);
        if (status && ["reconnecting", "failed", "ended"].includes(status.state)) sourceState(status.message);
        else if (status && status.state !== "paused") sourceState("");
      }
    }
  }

  function post(url, body) {
    return fetch(url, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) })
      .then((r) => r.json()).then((answer) => { if (answer.error) message(answer.error); return answer; });
  }

  async function startSource() {
    const source = info.source;
    if (source.kind === "image") {
      uploadSource(await loadImage("/api/image"));
      return;
    }
    if (source.kind === "video" && source.mime && $("video").canPlayType(source.mime)) {
      try {
        await playInBrowser();
        stats.decodedBy = "browser";
        return;
      } catch (error) {
        $("video").removeAttribute("src");
        sourceState(`the browser cannot play it (${error.message}); the server decodes it instead`);
      }
    }
    stats.decodedBy = "server";
    sourceState("waiting for the first frame");
    playFromServer();
  }

  // ------------------------------------------------------------------ the API

  // The source's first picture: the API waits for it (a view drawn before it would be black).
  let pictureArrived = null, pictureFailed = null;
  const firstPicture = new Promise((resolve, reject) => { pictureArrived = resolve; pictureFailed = reject; });
  firstPicture.catch(() => {});  // (a page that fails says so itself; the API's callers get the error)
  // The API's calls, one after another once the source's first picture is here: each set() is drawn before
  // the next one changes the view, and pixels() reads what the sets before it asked for.
  let apiQueue = firstPicture;
  function queued(action) {
    const done = apiQueue.then(action);
    apiQueue = done.catch(() => {});
    return done;
  }

  // Refuse what set() does not take, before anything changes.
  function checkView(view) {
    const known = ["yaw", "pitch", "roll", "fov", "width", "height", "mode", "strip", "start"];
    for (const key of Object.keys(view)) if (!known.includes(key)) throw new Error(`set: unknown key ${key}`);
    for (const key of ["yaw", "pitch", "roll", "fov", "width", "height", "start"]) {
      if (key in view && !Number.isFinite(view[key])) throw new Error(`set: ${key} must be a finite number`);
    }
    if ("mode" in view && !MODES.includes(view.mode)) throw new Error(`set: mode must be one of ${MODES.join(", ")}`);
  }

  // The view asked for, drawn from the source (its window uploaded first); the whole state.
  async function showView(view) {
    for (const key of ["yaw", "pitch", "roll", "fov", "width", "height", "mode"]) if (key in view) state[key] = view[key];
    if ("start" in view) state.panoramaStart = view.start;
    if ("strip" in view) state.strip = Boolean(view.strip);
    clampState();
    await ensureWindow();
    await ensureGains();
    if (!draw()) throw new Error("set: the view could not be drawn");
    showStateSoon();
    return { ...state };
  }

  function setView(view) {
    try {
      checkView(view);
    } catch (error) {
      return Promise.reject(error);
    }
    return queued(() => showView(view));
  }

  function summary(values) {
    if (!values.length) return null;
    const sorted = [...values].sort((a, b) => a - b);
    const at = (q) => sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))];
    return { count: values.length, mean: values.reduce((a, b) => a + b, 0) / values.length, min: sorted[0], median: at(0.5), p90: at(0.9), max: sorted[sorted.length - 1] };
  }

  window.panomapView = {
    set: setView,
    get: () => ({ ...state }),
    pixels: () => queued(async () => { await ensureWindow(); return viewPixels(); }),
    stats: () => ({
      views: stats.views,
      drawMs: summary(stats.drawMs),
      sourceFrames: stats.sourceFrames,
      frameTime: stats.frameTime,
      latencyMs: summary(stats.latencyMs),
      dragToPictureMs: summary(stats.dragToPictureMs),
      decodedBy: stats.decodedBy || (info && info.source.kind === "image" ? "image" : null),
      sourceWindow: shownWindow,
    }),
    commands: () => commands(),
  };

  // ------------------------------------------------------------------ start

  async function start() {
    try {
      info = await fetch("/api/info").then((r) => r.json());
      $("names").textContent = `${info.table.name} \u00b7 ${info.source.name}`;
      // A video's strip is off unless asked for: it needs the whole of every frame, the view only its part.
      state.strip = info.source.kind === "image";
      Object.assign(state, cameraView());
      readHash();
      const canvas = $("canvas");
      setUpGl(canvas);
      const binary = (url) => fetch(url).then((r) => {
        if (!r.ok) throw new Error(`the table did not load (HTTP ${r.status})`);
        return r.arrayBuffer();
      });
      if (info.rig) {
        linearFloat = Boolean(gl.getExtension("OES_texture_float_linear"));
        const lookups = await Promise.all(info.rig.cameras.map((_, k) => binary(`/api/rig/lookup.bin?camera=${k}`)));
        window.panomapRig.upload(gl, info.rig, lookups, linearFloat);
        $("names").textContent = `${info.table.name} \u00b7 ${info.rig.pictures.join(", ")}`;
      } else {
        uploadTable(await binary("/api/table.bin"), info.table.lookup ? await binary("/api/lookup.bin") : null);
      }
      setUpInput(canvas);
      await startSource();
      await ensureGains();
      draw();
      showState();
      document.body.dataset.ready = "yes";
    } catch (error) {
      message(String(error.message || error));
      document.body.dataset.ready = "failed";
      pictureFailed(new Error(`the viewer did not start: ${error.message || error}`));
    }
  }

  start();
})();

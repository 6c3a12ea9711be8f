/* brdf-viewer handout: the live view's runtime (written by viewer/handout/live.py).
 *
 * A classic script (no modules, no fetch: it works from file://). Each step's data script adds
 * window.BRDF_LIVE.steps[NN] (programs converted from the viewer's GLSL at build time, objects,
 * lights, camera, material uniform blocks and controls); meshes and environments are in
 * window.BRDF_LIVE.meshes / .envs. This script draws every <canvas data-step="NN"> it finds:
 * MSAA into a float target, resolve, then the converted tone-map pass, as the desktop raster does.
 * The camera follows the viewer's OrbitCamera (viewer/scene/camera.py) formula for formula. */
(function () {
  'use strict';
  var L = window.BRDF_LIVE = window.BRDF_LIVE || {steps: {}, meshes: {}, envs: {}, tables: {}};
  L.tables = L.tables || {};
  L.views = L.views || {};

  // ---------------------------------------------------------------- data
  function buffer(b64) {
    var s = atob(b64), n = s.length, u = new Uint8Array(n);
    for (var i = 0; i < n; i++) u[i] = s.charCodeAt(i);
    return u.buffer;
  }
  function f32(b64) { return new Float32Array(buffer(b64)); }
  function fmt(v) {
    if (typeof v === 'boolean') return v ? 'true' : 'false';
    if (typeof v === 'string') return v;
    if (Array.isArray(v)) return v.map(fmt).join(', ');
    if (v === 0) return '0';
    var s = Number(v.toPrecision(4));
    var a = Math.abs(s);
    if (a >= 1e-4 && a < 1e4) return String(s);
    return s.toExponential().replace(/e\+?/, 'e');
  }

  // ---------------------------------------------------------------- matrices
  // pyrr's row-major matrices (vector on the left): their flat arrays are what the desktop
  // uploads (gl_bytes of the column-convention matrix), so GLSL's M * v means the same here.
  function sub3(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
  function dot3(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
  function cross3(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
  function norm3(a) { var l = Math.sqrt(dot3(a, a)); return [a[0] / l, a[1] / l, a[2] / l]; }
  function lookAt(eye, target, up) {   // pyrr matrix44.create_look_at
    var f = norm3(sub3(target, eye)), s = norm3(cross3(f, up)), u = norm3(cross3(s, f));
    return [s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0,
            -dot3(s, eye), -dot3(u, eye), dot3(f, eye), 1];
  }
  function perspective(fovy, aspect, near, far) {   // pyrr create_perspective_projection
    var ymax = near * Math.tan(fovy * Math.PI / 360.0), xmax = ymax * aspect;
    var C = -(far + near) / (far - near), D = -2.0 * far * near / (far - near);
    return [near / xmax, 0, 0, 0, 0, near / ymax, 0, 0, 0, 0, C, -1, 0, 0, D, 0];
  }
  function mul(a, b) {   // row-major a @ b
    var o = new Array(16);
    for (var r = 0; r < 4; r++) for (var c = 0; c < 4; c++) {
      var s = 0; for (var k = 0; k < 4; k++) s += a[r * 4 + k] * b[k * 4 + c]; o[r * 4 + c] = s;
    }
    return o;
  }
  function inverse(m) {
    var a = m.slice(), inv = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
    for (var c = 0; c < 4; c++) {
      var p = c;
      for (var r = c + 1; r < 4; r++) if (Math.abs(a[r * 4 + c]) > Math.abs(a[p * 4 + c])) p = r;
      for (var k = 0; k < 4; k++) {
        var t = a[c * 4 + k]; a[c * 4 + k] = a[p * 4 + k]; a[p * 4 + k] = t;
        t = inv[c * 4 + k]; inv[c * 4 + k] = inv[p * 4 + k]; inv[p * 4 + k] = t;
      }
      var d = a[c * 4 + c];
      for (k = 0; k < 4; k++) { a[c * 4 + k] /= d; inv[c * 4 + k] /= d; }
      for (r = 0; r < 4; r++) if (r !== c) {
        var f = a[r * 4 + c];
        for (k = 0; k < 4; k++) { a[r * 4 + k] -= f * a[c * 4 + k]; inv[r * 4 + k] -= f * inv[c * 4 + k]; }
      }
    }
    return inv;
  }

  var PITCH_LIMIT = 89.0 * Math.PI / 180.0;
  function Camera(c) { this.c = c; this.reset(); }
  Camera.prototype.reset = function () {
    this.target = this.c.target.slice(); this.distance = this.c.distance;
    this.yaw = this.c.yaw; this.pitch = this.c.pitch; this.fov = this.c.fov_y;
  };
  Camera.prototype.position = function () {
    var cp = Math.cos(this.pitch), t = this.target, d = this.distance;
    return [t[0] + d * cp * Math.sin(this.yaw), t[1] + d * Math.sin(this.pitch), t[2] + d * cp * Math.cos(this.yaw)];
  };
  Camera.prototype.clip = function () {   // OrbitCamera.clip_planes: near and far from the scene's bounds
    var lo = this.c.bounds[0], hi = this.c.bounds[1];
    var center = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2];
    var ext = sub3(hi, lo), radius = 0.5 * Math.sqrt(dot3(ext, ext)) + 1e-3;
    var q = sub3(this.position(), center), dist = Math.sqrt(dot3(q, q));
    var far = dist + radius * 1.05;
    return [Math.max(dist - radius * 1.05, far * 1e-4, 1e-3), far];
  };
  Camera.prototype.viewProj = function (aspect) {   // (P @ V) as the desktop uploads it
    var nf = this.clip();
    return mul(lookAt(this.position(), this.target, this.c.up), perspective(this.fov, aspect, nf[0], nf[1]));
  };
  Camera.prototype.orbit = function (dx, dy, vh) {
    var k = Math.PI / Math.max(vh, 1.0);
    this.yaw -= dx * k;
    this.pitch = Math.max(-PITCH_LIMIT, Math.min(PITCH_LIMIT, this.pitch + dy * k));
  };
  Camera.prototype.dolly = function (steps) { this.distance = Math.max(1e-3, this.distance * Math.pow(0.9, steps)); };

  // ---------------------------------------------------------------- GL helpers
  var ATTRIBS = {in_position: 0, in_normal: 1, in_tangent: 2, in_geometric_normal: 3, in_model: 4, in_normal_matrix: 8};

  function compile(gl, src, key, step) {
    var p = gl.createProgram(), ok = true, log = '';
    [[gl.VERTEX_SHADER, src.vs, 'vertex'], [gl.FRAGMENT_SHADER, src.fs, 'fragment']].forEach(function (s) {
      var sh = gl.createShader(s[0]);
      gl.shaderSource(sh, s[1]);
      gl.compileShader(sh);
      if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) { ok = false; log += s[2] + ': ' + gl.getShaderInfoLog(sh); }
      gl.attachShader(p, sh);
    });
    Object.keys(ATTRIBS).forEach(function (a) { gl.bindAttribLocation(p, ATTRIBS[a], a); });
    if (ok) {
      gl.linkProgram(p);
      if (!gl.getProgramParameter(p, gl.LINK_STATUS)) { ok = false; log += 'link: ' + gl.getProgramInfoLog(p); }
    }
    if (!ok) throw new Error('brdf live view, step ' + step + ', program ' + key + ': ' + log);
    var info = {program: p, uniforms: {}, samplers: []};
    var n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS);
    var samplerTypes = [gl.SAMPLER_2D, gl.SAMPLER_3D, gl.SAMPLER_2D_ARRAY, gl.SAMPLER_2D_SHADOW, gl.SAMPLER_CUBE,
                        gl.INT_SAMPLER_2D, gl.UNSIGNED_INT_SAMPLER_2D];
    gl.useProgram(p);
    for (var i = 0; i < n; i++) {
      var u = gl.getActiveUniform(p, i), name = u.name.replace(/\[0\]$/, '');
      var loc = gl.getUniformLocation(p, u.name);
      info.uniforms[name] = {type: u.type, size: u.size, loc: loc};
      if (samplerTypes.indexOf(u.type) >= 0) {   // every sampler its own unit: no two types share one
        gl.uniform1i(loc, info.samplers.length);
        info.samplers.push({name: name, type: u.type, unit: info.samplers.length});
      }
    }
    return info;
  }

  function setUniform(gl, info, name, value) {
    var u = info.uniforms[name];
    if (!u || value === undefined || value === null) return;
    var t = u.type;
    var ints = [gl.INT, gl.INT_VEC2, gl.INT_VEC3, gl.INT_VEC4, gl.BOOL, gl.UNSIGNED_INT];
    var isInt = ints.indexOf(t) >= 0;
    var data;
    if (value.b64 !== undefined) data = isInt ? new Int32Array(buffer(value.b64)) : new Float32Array(buffer(value.b64));
    else if (value instanceof Float32Array || value instanceof Int32Array) data = isInt ? Int32Array.from(value) : value;
    else data = isInt ? Int32Array.from(value, function (x) { return Math.round(x); }) : Float32Array.from(value);
    var comps = {};
    comps[gl.FLOAT] = 1; comps[gl.FLOAT_VEC2] = 2; comps[gl.FLOAT_VEC3] = 3; comps[gl.FLOAT_VEC4] = 4;
    comps[gl.INT] = 1; comps[gl.INT_VEC2] = 2; comps[gl.INT_VEC3] = 3; comps[gl.INT_VEC4] = 4; comps[gl.BOOL] = 1;
    comps[gl.UNSIGNED_INT] = 1; comps[gl.FLOAT_MAT3] = 9; comps[gl.FLOAT_MAT4] = 16;
    var k = comps[t];
    if (!k) return;
    var n = Math.min(u.size, Math.floor(data.length / k));
    if (n < 1) return;
    data = data.subarray(0, n * k);
    switch (t) {
      case gl.FLOAT: gl.uniform1fv(u.loc, data); break;
      case gl.FLOAT_VEC2: gl.uniform2fv(u.loc, data); break;
      case gl.FLOAT_VEC3: gl.uniform3fv(u.loc, data); break;
      case gl.FLOAT_VEC4: gl.uniform4fv(u.loc, data); break;
      case gl.INT: case gl.BOOL: gl.uniform1iv(u.loc, data); break;
      case gl.INT_VEC2: gl.uniform2iv(u.loc, data); break;
      case gl.INT_VEC3: gl.uniform3iv(u.loc, data); break;
      case gl.INT_VEC4: gl.uniform4iv(u.loc, data); break;
      case gl.UNSIGNED_INT: gl.uniform1uiv(u.loc, Uint32Array.from(data)); break;
      case gl.FLOAT_MAT3: gl.uniformMatrix3fv(u.loc, false, data); break;
      case gl.FLOAT_MAT4: gl.uniformMatrix4fv(u.loc, false, data); break;
    }
  }

  function texture(gl, target, internal, format, type, w, h, d, data, linear, repeatS) {
    var t = gl.createTexture();
    gl.bindTexture(target, t);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    if (target === gl.TEXTURE_2D_ARRAY || target === gl.TEXTURE_3D) gl.texImage3D(target, 0, internal, w, h, d, 0, format, type, data);
    else gl.texImage2D(target, 0, internal, w, h, 0, format, type, data);
    var f = linear ? gl.LINEAR : gl.NEAREST;
    gl.texParameteri(target, gl.TEXTURE_MIN_FILTER, f);
    gl.texParameteri(target, gl.TEXTURE_MAG_FILTER, f);
    gl.texParameteri(target, gl.TEXTURE_WRAP_S, repeatS ? gl.REPEAT : gl.CLAMP_TO_EDGE);
    gl.texParameteri(target, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    return t;
  }

  // ---------------------------------------------------------------- one view
  function View(canvas, d, root) {
    this.canvas = canvas; this.d = d; this.root = root;
    this.status = root ? root.querySelector('[data-status-for="' + d.step + '"]') : null;
    this.camera = new Camera(d.camera);
    this.frames = 0;
    this.fixedSize = null;
    var gl = canvas.getContext('webgl2', {antialias: false, alpha: false, depth: false, preserveDrawingBuffer: false});
    if (!gl) { this.say('This browser has no WebGL2: the live view needs it (the still images show the step).'); return; }
    if (!gl.getExtension('EXT_color_buffer_float')) {
      this.say('This browser cannot render to float targets (EXT_color_buffer_float): the live view needs it.');
      return;
    }
    this.gl = gl;
    try { this.setup(); } catch (e) { this.say('The live view could not start: ' + e.message); console.error(e.message); this.gl = null; return; }
    this.wire();
    this.ready = true;
    if (L.manual) return;   // a script (a test) draws with readPixels and nothing else
    this.resize();
    this.request();
  }
  View.prototype.say = function (text) { if (this.status) this.status.textContent = text; };

  View.prototype.setup = function () {
    var gl = this.gl, d = this.d, self = this;
    this.programs = {};
    Object.keys(d.programs).forEach(function (k) { self.programs[k] = compile(gl, d.programs[k], k, d.step); });
    this.tonemap = compile(gl, d.tonemap, 'tonemap', d.step);
    this.background = d.background ? compile(gl, d.background, 'background', d.step) : null;
    // textures: the environment's and one empty texture per sampler type for the rest
    this.textures = {};
    var env = d.env ? L.envs[d.env] : null;
    if (d.env && !env) throw new Error('its environment data did not load');
    // half floats, or float32 where a value does not fit (then linear filtering needs an extension)
    var floats = function (target, channels, w, h, dd, data, repeat) {
      var rgb = channels === 3;
      if (data.f16 !== undefined) {
        return texture(gl, target, rgb ? gl.RGB16F : gl.RG16F, rgb ? gl.RGB : gl.RG, gl.HALF_FLOAT, w, h, dd,
                       new Uint16Array(buffer(data.f16)), true, repeat);
      }
      if (!gl.getExtension('OES_texture_float_linear')) throw new Error('this browser cannot filter float textures (OES_texture_float_linear), which this environment needs');
      return texture(gl, target, rgb ? gl.RGB32F : gl.RG32F, rgb ? gl.RGB : gl.RG, gl.FLOAT, w, h, dd, f32(data.f32), true, repeat);
    };
    if (env) {
      if (env.map) this.textures.u_env_map = floats(gl.TEXTURE_2D, 3, env.map[0], env.map[1], 1, env.map_data, true);
      var ly = env.layers;
      this.textures.u_env_prefiltered = floats(gl.TEXTURE_2D_ARRAY, 3, ly[0], ly[1], ly[2], env.prefiltered, true);
      this.textures.u_env_dfg = floats(gl.TEXTURE_2D, 2, env.dfg[0], env.dfg[1], 1, env.dfg_data, false);
    }
    var zero = new Uint8Array(4);
    this.empty = {};
    this.empty[gl.SAMPLER_2D] = texture(gl, gl.TEXTURE_2D, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, 1, 1, 1, zero, false, false);
    this.empty[gl.SAMPLER_2D_ARRAY] = texture(gl, gl.TEXTURE_2D_ARRAY, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, 1, 1, 1, zero, false, false);
    this.empty[gl.SAMPLER_3D] = texture(gl, gl.TEXTURE_3D, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, 1, 1, 1, zero, false, false);
    var depth = texture(gl, gl.TEXTURE_2D, gl.DEPTH_COMPONENT16, gl.DEPTH_COMPONENT, gl.UNSIGNED_SHORT, 1, 1, 1,
                        new Uint16Array([65535]), false, false);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_COMPARE_MODE, gl.COMPARE_REF_TO_TEXTURE);
    this.empty[gl.SAMPLER_2D_SHADOW] = depth;
    this.emptyTarget = {};
    this.emptyTarget[gl.SAMPLER_2D] = gl.TEXTURE_2D; this.emptyTarget[gl.SAMPLER_2D_SHADOW] = gl.TEXTURE_2D;
    this.emptyTarget[gl.SAMPLER_2D_ARRAY] = gl.TEXTURE_2D_ARRAY; this.emptyTarget[gl.SAMPLER_3D] = gl.TEXTURE_3D;
    this.texTarget = {u_env_map: gl.TEXTURE_2D, u_env_prefiltered: gl.TEXTURE_2D_ARRAY, u_env_dfg: gl.TEXTURE_2D};
    // objects: each mesh as triangle corners, with the geometric normal forward.geom computed
    this.objects = d.objects.map(function (o) { return self.object(o); });
    this.materials = {};
    Object.keys(d.materials).forEach(function (name) {
      var m = d.materials[name];
      var block = m.uniforms.u_mat && m.uniforms.u_mat.b64 ? f32(m.uniforms.u_mat.b64) : new Float32Array(256);
      var own = {};
      Object.keys(m.textures || {}).forEach(function (u) {   // a measured table: float32 RGB, read with texelFetch
        var t = L.tables[m.textures[u]];
        if (!t) throw new Error('its measured table did not load');
        own[u] = texture(gl, gl.TEXTURE_3D, gl.RGB32F, gl.RGB, gl.FLOAT, t.size[0], t.size[1], t.size[2], f32(t.data), false, false);
      });
      self.materials[name] = {d: m, block: block, stepBlock: block.slice(), base: block.slice(), textures: own};
    });
  };

  View.prototype.object = function (o) {
    var gl = this.gl, mesh = L.meshes[o.mesh];
    if (!mesh) throw new Error('its mesh data did not load');
    var P = f32(mesh.positions), N = f32(mesh.normals), T = f32(mesh.tangents), I = new Uint32Array(buffer(mesh.indices));
    var n = I.length, pos = new Float32Array(n * 3), nrm = new Float32Array(n * 3), tan = new Float32Array(n * 4),
        geo = new Float32Array(n * 3), M = o.model;
    for (var c = 0; c < n; c++) {
      var v = I[c];
      pos.set(P.subarray(3 * v, 3 * v + 3), 3 * c); nrm.set(N.subarray(3 * v, 3 * v + 3), 3 * c);
      tan.set(T.subarray(4 * v, 4 * v + 4), 4 * c);
    }
    function world(i) {   // column-major model matrix times (x, y, z, 1)
      var x = pos[3 * i], y = pos[3 * i + 1], z = pos[3 * i + 2];
      return [M[0] * x + M[4] * y + M[8] * z + M[12], M[1] * x + M[5] * y + M[9] * z + M[13], M[2] * x + M[6] * y + M[10] * z + M[14]];
    }
    for (var t = 0; t < n; t += 3) {   // passes/forward.geom: normalize(cross(p1 - p0, p2 - p0)), else +z
      var p0 = world(t), g = cross3(sub3(world(t + 1), p0), sub3(world(t + 2), p0));
      var len = Math.sqrt(dot3(g, g));
      g = len > 0 ? [g[0] / len, g[1] / len, g[2] / len] : [0, 0, 1];
      for (var k = 0; k < 3; k++) geo.set(g, 3 * (t + k));
    }
    var vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    [[pos, 0, 3], [nrm, 1, 3], [tan, 2, 4], [geo, 3, 3]].forEach(function (a) {
      var b = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, b);
      gl.bufferData(gl.ARRAY_BUFFER, a[0], gl.STATIC_DRAW);
      gl.enableVertexAttribArray(a[1]);
      gl.vertexAttribPointer(a[1], a[2], gl.FLOAT, false, 0, 0);
    });
    gl.bindVertexArray(null);
    return {d: o, vao: vao, count: n};
  };

  View.prototype.targets = function (w, h) {
    var gl = this.gl;
    if (this.tg && this.tg.w === w && this.tg.h === h) return this.tg;
    if (this.tg) this.tg.release();
    var fmt = gl.RGBA32F, want = Math.max(0, this.d.msaa | 0);
    var samples = 0;
    if (want > 1) {
      var s32 = gl.getInternalformatParameter(gl.RENDERBUFFER, gl.RGBA32F, gl.SAMPLES) || [];
      var s16 = gl.getInternalformatParameter(gl.RENDERBUFFER, gl.RGBA16F, gl.SAMPLES) || [];
      var fits = function (list) { for (var i = 0; i < list.length; i++) if (list[i] <= want) return list[i]; return 0; };
      samples = fits(s32);
      if (!samples && fits(s16)) { fmt = gl.RGBA16F; samples = fits(s16); }
    }
    var tg = {w: w, h: h, samples: samples};
    tg.resolved = texture(gl, gl.TEXTURE_2D, gl.RGBA32F, gl.RGBA, gl.FLOAT, w, h, 1, null, false, false);
    tg.resolveFbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, tg.resolveFbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tg.resolved, 0);
    tg.depth = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, tg.depth);
    if (samples) {
      tg.color = gl.createRenderbuffer();
      gl.bindRenderbuffer(gl.RENDERBUFFER, tg.color);
      gl.renderbufferStorageMultisample(gl.RENDERBUFFER, samples, fmt, w, h);
      gl.bindRenderbuffer(gl.RENDERBUFFER, tg.depth);
      gl.renderbufferStorageMultisample(gl.RENDERBUFFER, samples, gl.DEPTH_COMPONENT24, w, h);
      tg.drawFbo = gl.createFramebuffer();
      gl.bindFramebuffer(gl.FRAMEBUFFER, tg.drawFbo);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.RENDERBUFFER, tg.color);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, tg.depth);
    } else {
      gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, w, h);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, tg.depth);
      tg.drawFbo = tg.resolveFbo;
    }
    if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) throw new Error('its float render target is not supported here');
    tg.release = function () {
      gl.deleteTexture(tg.resolved); gl.deleteRenderbuffer(tg.depth);
      if (tg.color) { gl.deleteRenderbuffer(tg.color); gl.deleteFramebuffer(tg.drawFbo); }
      gl.deleteFramebuffer(tg.resolveFbo);
    };
    this.tg = tg;
    return tg;
  };

  View.prototype.bindSamplers = function (info, own) {
    var gl = this.gl, self = this;
    info.samplers.forEach(function (s) {
      gl.activeTexture(gl.TEXTURE0 + s.unit);
      var t = self.textures[s.name];
      if (own && own[s.name]) gl.bindTexture(gl.TEXTURE_3D, own[s.name]);
      else if (t) gl.bindTexture(self.texTarget[s.name], t);
      else gl.bindTexture(self.emptyTarget[s.type] || gl.TEXTURE_2D, self.empty[s.type] || self.empty[gl.SAMPLER_2D]);
    });
  };

  View.prototype.draw = function () {
    var gl = this.gl, d = this.d, self = this;
    var w = this.canvas.width, h = this.canvas.height;
    var tg = this.targets(w, h);
    var vp = this.camera.viewProj(w / h), eye = this.camera.position();
    this.lastViewProj = vp;
    gl.bindFramebuffer(gl.FRAMEBUFFER, tg.drawFbo);
    gl.viewport(0, 0, w, h);
    gl.disable(gl.BLEND);
    gl.depthMask(true);
    gl.clearColor(d.clear[0], d.clear[1], d.clear[2], 1.0);
    gl.clearDepth(1.0);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.bindVertexArray(null);
    if (this.background) {   // the environment behind the scene (passes/background.frag)
      gl.disable(gl.DEPTH_TEST);
      var bg = this.background;
      gl.useProgram(bg.program);
      Object.keys(d.env_uniforms).forEach(function (k) { setUniform(gl, bg, k, d.env_uniforms[k]); });
      setUniform(gl, bg, 'u_inv_view_proj', inverse(vp));
      setUniform(gl, bg, 'u_camera_pos', eye);
      this.bindSamplers(bg);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
    }
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LESS);
    gl.disable(gl.CULL_FACE);
    this.objects.forEach(function (o) {
      var m = self.materials[o.d.material], info = self.programs[m.d.program];
      gl.useProgram(info.program);
      Object.keys(d.frame_uniforms).forEach(function (k) { setUniform(gl, info, k, d.frame_uniforms[k]); });
      Object.keys(d.env_uniforms).forEach(function (k) { setUniform(gl, info, k, d.env_uniforms[k]); });
      Object.keys(m.d.uniforms).forEach(function (k) { if (k !== 'u_mat') setUniform(gl, info, k, m.d.uniforms[k]); });
      setUniform(gl, info, 'u_mat', m.block);
      setUniform(gl, info, 'u_view_proj', vp);
      setUniform(gl, info, 'u_camera_pos', eye);
      self.bindSamplers(info, m.textures);
      var M = o.d.model, Nm = o.d.normal;
      for (var c = 0; c < 4; c++) gl.vertexAttrib4f(ATTRIBS.in_model + c, M[4 * c], M[4 * c + 1], M[4 * c + 2], M[4 * c + 3]);
      for (c = 0; c < 3; c++) gl.vertexAttrib3f(ATTRIBS.in_normal_matrix + c, Nm[3 * c], Nm[3 * c + 1], Nm[3 * c + 2]);
      gl.bindVertexArray(o.vao);
      gl.drawArrays(gl.TRIANGLES, 0, o.count);
    });
    gl.bindVertexArray(null);
    if (tg.samples) {   // the MSAA resolve
      gl.bindFramebuffer(gl.READ_FRAMEBUFFER, tg.drawFbo);
      gl.bindFramebuffer(gl.DRAW_FRAMEBUFFER, tg.resolveFbo);
      gl.blitFramebuffer(0, 0, w, h, 0, 0, w, h, gl.COLOR_BUFFER_BIT, gl.NEAREST);
    }
    // exposure, tone mapping and sRGB encoding into the canvas (passes/tonemap.frag)
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, w, h);
    gl.disable(gl.DEPTH_TEST);
    var tm = this.tonemap;
    gl.useProgram(tm.program);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, tg.resolved);
    setUniform(gl, tm, 'u_hdr', [0]);
    setUniform(gl, tm, 'u_exposure', [d.exposure]);
    setUniform(gl, tm, 'u_tonemap', [d.tonemap_mode]);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    this.frames += 1;
    if (this.frames === 1) this.say('');
  };

  View.prototype.request = function () {
    var self = this;
    if (!this.gl || this.pending) return;
    this.pending = true;
    requestAnimationFrame(function () {
      self.pending = false;
      try { self.draw(); } catch (e) { self.say('The live view stopped: ' + e.message); console.error(e.message); self.gl = null; }
    });
  };

  View.prototype.resize = function () {
    if (this.fixedSize) return;
    var c = this.canvas, dpr = Math.min(window.devicePixelRatio || 1, 2);
    var cw = c.clientWidth || this.d.size[0];
    var w = Math.max(1, Math.min(Math.round(cw * dpr), 1280));
    var h = Math.max(1, Math.round(w * this.d.size[1] / this.d.size[0]));
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; this.request(); }
  };

  // ---------------------------------------------------------------- input: orbit and controls
  View.prototype.wire = function () {
    var self = this, c = this.canvas, pts = {};
    c.addEventListener('pointerdown', function (e) {
      c.setPointerCapture(e.pointerId); pts[e.pointerId] = [e.clientX, e.clientY]; e.preventDefault();
    });
    c.addEventListener('pointermove', function (e) {
      var p = pts[e.pointerId];
      if (!p) return;
      var ids = Object.keys(pts);
      if (ids.length === 1) {
        self.camera.orbit(e.clientX - p[0], e.clientY - p[1], c.clientHeight);
      } else if (ids.length === 2) {   // pinch: the change in the fingers' distance dollies
        var o = pts[ids[0] === String(e.pointerId) ? ids[1] : ids[0]];
        var d0 = Math.hypot(p[0] - o[0], p[1] - o[1]), d1 = Math.hypot(e.clientX - o[0], e.clientY - o[1]);
        if (d0 > 0 && d1 > 0) self.camera.dolly(Math.log(d1 / d0) / -Math.log(0.9));
      }
      pts[e.pointerId] = [e.clientX, e.clientY];
      self.request();
    });
    var up = function (e) { delete pts[e.pointerId]; };
    c.addEventListener('pointerup', up);
    c.addEventListener('pointercancel', up);
    c.addEventListener('wheel', function (e) {
      e.preventDefault();
      var dy = e.deltaY * (e.deltaMode === 1 ? 33 : e.deltaMode === 2 ? 400 : 1);
      self.camera.dolly(-dy / 100.0);
      self.request();
    }, {passive: false});
    c.addEventListener('dblclick', function () { self.camera.reset(); self.request(); });
    if (window.ResizeObserver) new ResizeObserver(function () { self.resize(); }).observe(c);
    else window.addEventListener('resize', function () { self.resize(); });
    if (!this.root) return;
    Object.keys(this.materials).forEach(function (name) {
      var m = self.materials[name];
      m.controls = m.d.controls.filter(function (ctl) { return ctl.kind !== 'heading'; });
      m.controls.forEach(function (ctl) {
        ctl.stepValue = ctl.value;
        ctl.inputs = Array.prototype.slice.call(self.root.querySelectorAll('[data-param="' + ctl.param + '"]'));
        ctl.output = self.root.querySelector('[data-value-for="' + ctl.param + '"]');
        ctl.row = self.root.querySelector('[data-row="' + ctl.param + '"]');
        ctl.inputs.forEach(function (inp) {
          inp.addEventListener(ctl.kind === 'select' || ctl.kind === 'color' || ctl.kind === 'checkbox' ? 'change' : 'input',
                               function () { self.changed(m, ctl, inp); });
          if (ctl.kind === 'color') inp.addEventListener('input', function () { self.changed(m, ctl, inp); });
        });
        if (ctl.output) ctl.output.textContent = shown(ctl, ctl.value);
      });
      self.visibility(m);
    });
  };

  function fromSlider(ctl, x) {
    if (ctl.scale === 'log10') return Math.pow(10, x);
    if (ctl.scale === 'sqrt') return x * x;
    return x;
  }
  function toSlider(ctl, v) {
    if (ctl.scale === 'log10') return Math.log10(v);
    if (ctl.scale === 'sqrt') return Math.sqrt(Math.max(v, 0));
    return v;
  }
  // the read-out: a roughness slider shows r and the model's alpha = r^2; a picker shows nothing more
  function shown(ctl, v) {
    if (ctl.kind === 'select') return '';
    if (ctl.scale === 'sqrt') return fmt(Math.sqrt(v)) + ' (\u03b1 ' + fmt(v) + ')';
    return fmt(v);
  }
  function hexRgb(s) { return [1, 3, 5].map(function (i) { return parseInt(s.substr(i, 2), 16) / 255; }); }

  View.prototype.changed = function (m, ctl, inp) {
    var v;
    if (ctl.kind === 'range') {
      v = fromSlider(ctl, parseFloat(inp.value));
      if (ctl.mode === 'stops') {   // the nearest value whose block Python computed
        var best = ctl.stops[0];
        ctl.stops.forEach(function (s) {
          if (Math.abs(toSlider(ctl, s.value) - parseFloat(inp.value)) < Math.abs(toSlider(ctl, best.value) - parseFloat(inp.value))) best = s;
        });
        v = best.value;
        inp.value = String(toSlider(ctl, v));
        this.rebase(m, ctl, f32(best.block));
      }
    } else if (ctl.kind === 'color') {
      v = hexRgb(inp.value);
    } else if (ctl.kind === 'rgb') {
      v = ctl.inputs.map(function (x) { return parseFloat(x.value); });
    } else if (ctl.kind === 'checkbox') {
      v = !!inp.checked;
      if (ctl.mode === 'stops') {
        var st = ctl.stops.filter(function (s) { return s.value === v; })[0];
        if (st) this.rebase(m, ctl, f32(st.block));
      }
    } else if (ctl.kind === 'select') {
      v = inp.value;
      var opt = ctl.options.filter(function (o) { return o.value === v; })[0];
      if (!opt || !opt.block) { inp.value = ctl.value; return; }
      this.rebase(m, ctl, f32(opt.block));
    }
    ctl.value = v;
    this.apply(m);
    if (ctl.output) ctl.output.textContent = shown(ctl, v);
    if (ctl.kind === 'select') this.visibility(m);
    var baked = this.root.querySelector('[data-baked-for="' + m.d.name + '"]');
    var moved = m.controls.some(function (c) { return JSON.stringify(c.value) !== JSON.stringify(c.stepValue); });
    if (baked) baked.hidden = !(moved && m.d.uniforms.u_env_on === undefined && this.d.frame_uniforms.u_env_on && this.d.frame_uniforms.u_env_on[0]);
    this.request();
  };

  // A control whose value moves more than its own floats: its block becomes the base, and the
  // other such controls go back to the step's values (their blocks were computed with them).
  View.prototype.rebase = function (m, ctl, block) {
    m.base = block;
    m.controls.forEach(function (c) {
      if (c === ctl || (c.mode !== 'stops' && c.mode !== 'choice')) return;
      c.value = c.stepValue;
      c.inputs.forEach(function (inp) {
        if (c.kind === 'select') inp.value = c.value;
        else if (c.kind === 'checkbox') inp.checked = !!c.value;
        else inp.value = String(toSlider(c, c.value));
      });
      if (c.output) c.output.textContent = shown(c, c.value);
    });
  };

  // The block: the base (the step's, or a stop's) with every direct control's value written in.
  View.prototype.apply = function (m) {
    var b = m.base.slice();
    m.controls.forEach(function (c) {
      if (c.mode !== 'direct') return;
      if (c.kind === 'range') c.slots.forEach(function (i) { b[i] = c.value; });
      else if (c.kind === 'checkbox') c.slots.forEach(function (i) { b[i] = c.value ? 1 : 0; });
      else c.slots.forEach(function (i, k) { b[i] = c.value[k]; });
    });
    m.block = b;
  };

  // editor_rules.shown_params, tabulated in Python for every combination of a level's choices:
  // a parameter of that level is shown iff the current combination lists it
  View.prototype.visibility = function (m) {
    var level = function (sub) { var i = sub.lastIndexOf('.'); return i < 0 ? '' : sub.slice(0, i + 1); };
    var bySub = {};
    m.controls.forEach(function (c) { bySub[c.sub] = c; });
    var shown = m.d.shown || {};
    m.controls.forEach(function (c) {
      if (!c.row) return;
      var show = !c.hidden, t = shown[level(c.sub)];
      if (t && t.choices.indexOf(c.sub) < 0) {
        var key = t.choices.map(function (s) { return bySub[s] ? bySub[s].value : ''; }).join('|');
        var list = t.table[key];
        if (list) show = list.indexOf(c.sub) >= 0;
      }
      c.row.classList.toggle('brdf-live-hidden', !show);
    });
  };

  // ---------------------------------------------------------------- for tests and scripts
  // Render at w x h now and return the canvas's RGBA bytes (rows bottom to top) as base64.
  View.prototype.readPixels = function (w, h) {
    var gl = this.gl;
    this.fixedSize = [w, h];
    this.canvas.width = w; this.canvas.height = h;
    this.draw();
    var px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    var s = '';
    for (var i = 0; i < px.length; i += 8192) s += String.fromCharCode.apply(null, px.subarray(i, i + 8192));
    return btoa(s);
  };
  View.prototype.viewProj = function (aspect) { return this.camera.viewProj(aspect); };

  function init() {
    var canvases = document.querySelectorAll('canvas[data-step]');
    for (var i = 0; i < canvases.length; i++) {
      var c = canvases[i], step = c.getAttribute('data-step'), d = L.steps[step];
      if (!d || L.views[step]) continue;
      var root = c.closest('.brdf-live');
      for (var name in d.materials) d.materials[name].name = name;
      L.views[step] = new View(c, d, root);
    }
  }
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', init);
  else init();
})();

// The 3D views of a contopt report.html: vanilla WebGL 1, no library, no network.
// Reads the scene from <script type="application/json" id="contopt-scene"> (meshes as base64
// typed arrays, see contopt/io/webview.py) and fills every <div class="cv-view" data-view=ID>.
// Mouse: left drag orbits, right drag (or shift + left drag) pans, the wheel zooms,
// a double click resets the camera. window.contoptReport says what was drawn (for tests).
(function () {
  "use strict";
  var status = { ready: false, errors: [], views: {} };
  window.contoptReport = status;

  function fail(msg, where) {
    status.errors.push(msg);
    console.error("contopt report: " + msg);
    if (where) {
      var p = document.createElement("p");
      p.className = "cv-error";
      p.textContent = msg;
      where.appendChild(p);
    }
  }

  function decode(b64, Type) {
    var bin = atob(b64), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Type(bytes.buffer);
  }

  // ---- small column-major 4x4 matrix helpers --------------------------------------------------
  function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
  function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
  function unit(a) { var l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; }
  function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
  function lookAt(eye, target, up) {
    var f = unit(sub(target, eye)), s = unit(cross(f, up)), u = cross(s, f);
    return [s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0,
            -dot(s, eye), -dot(u, eye), dot(f, eye), 1];
  }
  function perspective(fovy, aspect, near, far) {
    var t = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
    return [t / aspect, 0, 0, 0, 0, t, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0];
  }

  var FOVY = Math.PI / 6;  // vertical field of view (30 degrees)
  var VS = [
    "attribute vec3 aPos; attribute vec3 aNormal; attribute float aValue;",
    "uniform mat4 uView; uniform mat4 uProj; uniform mat3 uNormal;",
    "varying vec3 vN; varying float vValue;",
    "void main() { vN = uNormal * aNormal; vValue = aValue; gl_Position = uProj * uView * vec4(aPos, 1.0); }"
  ].join("\n");
  var FS = [
    "#ifdef GL_FRAGMENT_PRECISION_HIGH\nprecision highp float;\n#else\nprecision mediump float;\n#endif",
    "varying vec3 vN; varying float vValue;",
    "uniform vec3 uColor; uniform float uOpacity; uniform float uUseLut; uniform sampler2D uLut; uniform vec2 uRange;",
    "void main() {",
    "  float d = abs(normalize(vN).z);",  // a headlight, both sides of a face lit alike
    "  vec3 base = uColor;",
    "  if (uUseLut > 0.5) {",
    "    float t = clamp((vValue - uRange.x) / (uRange.y - uRange.x), 0.0, 1.0);",
    "    base = texture2D(uLut, vec2((t * 255.0 + 0.5) / 256.0, 0.5)).rgb;",
    "  }",
    "  gl_FragColor = vec4(base * (0.35 + 0.65 * d) + vec3(0.10) * pow(d, 24.0), uOpacity);",
    "}"
  ].join("\n");

  function program(gl) {
    function shader(type, src) {
      var s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(s));
      return s;
    }
    var p = gl.createProgram();
    gl.attachShader(p, shader(gl.VERTEX_SHADER, VS));
    gl.attachShader(p, shader(gl.FRAGMENT_SHADER, FS));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error("program: " + gl.getProgramInfoLog(p));
    var loc = { prog: p };
    ["aPos", "aNormal", "aValue"].forEach(function (n) { loc[n] = gl.getAttribLocation(p, n); });
    ["uView", "uProj", "uNormal", "uColor", "uOpacity", "uUseLut", "uLut", "uRange"].forEach(function (n) {
      loc[n] = gl.getUniformLocation(p, n);
    });
    return loc;
  }

  // vertex normals: the area-weighted face normals around each vertex
  function normals(pos, tri) {
    var n = new Float32Array(pos.length);
    for (var t = 0; t < tri.length; t += 3) {
      var a = 3 * tri[t], b = 3 * tri[t + 1], c = 3 * tri[t + 2];
      var e1 = [pos[b] - pos[a], pos[b + 1] - pos[a + 1], pos[b + 2] - pos[a + 2]];
      var e2 = [pos[c] - pos[a], pos[c + 1] - pos[a + 1], pos[c + 2] - pos[a + 2]];
      var f = cross(e1, e2);
      for (var k = 0; k < 3; k++) { n[a + k] += f[k]; n[b + k] += f[k]; n[c + k] += f[k]; }
    }
    return n;
  }

  function decodeMesh(m) {
    return {
      info: m,
      points: decode(m.points, Float32Array),
      displacement: decode(m.displacement, Float32Array),
      values: m.values === null ? null : decode(m.values, Float32Array),
      triangles: decode(m.triangles, m.index_bytes === 2 ? Uint16Array : Uint32Array)
    };
  }

  function bounds(meshes) {
    var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    meshes.forEach(function (m) {
      for (var i = 0; i < m.points.length; i += 3) {
        for (var k = 0; k < 3; k++) {
          lo[k] = Math.min(lo[k], m.points[i + k], m.points[i + k] + m.displacement[i + k]);
          hi[k] = Math.max(hi[k], m.points[i + k], m.points[i + k] + m.displacement[i + k]);
        }
      }
    });
    if (!isFinite(lo[0])) { lo = [0, 0, 0]; hi = [1, 1, 1]; }
    return { lo: lo, hi: hi, center: [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2],
             radius: Math.max(0.5 * Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]), 1e-9) };
  }

  function View(el, scene, meshes, spec, box) {
    this.el = el; this.scene = scene; this.spec = spec; this.box = box;
    this.scale = spec.deformed ? 1.0 : 0.0;
    this.canvas = document.createElement("canvas");
    this.canvas.className = "cv-canvas";
    el.appendChild(this.canvas);
    // alpha: false, or the canvas's translucent pixels would show the page through the blended surfaces
    var attrs = { alpha: false, antialias: true, preserveDrawingBuffer: true };
    var gl = this.canvas.getContext("webgl", attrs) || this.canvas.getContext("experimental-webgl", attrs);
    if (!gl) throw new Error("WebGL is not available in this browser; the pictures below show the same run");
    this.gl = gl;
    this.uint32 = !!gl.getExtension("OES_element_index_uint");
    this.loc = program(gl);
    this.lut = this.makeLut(decode(scene.lut, Uint8Array));
    this.items = meshes.map(this.upload, this);
    this.reset();
    this.controls();
    this.mouse();
    var self = this;
    window.addEventListener("resize", function () { self.draw(); });
  }

  View.prototype.makeLut = function (rgb) {
    var gl = this.gl, tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGB, rgb.length / 3, 1, 0, gl.RGB, gl.UNSIGNED_BYTE, rgb);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    return tex;
  };

  View.prototype.upload = function (m) {
    var gl = this.gl, style = this.spec.styles[m.info.role];
    if (m.triangles instanceof Uint32Array && !this.uint32) {
      throw new Error("this browser's WebGL cannot draw meshes of over 65535 vertices (no OES_element_index_uint)");
    }
    var useLut = this.spec.colour_by_values && m.values !== null && style.values;
    // a body without values in a coloured view (the mortar side: a die) is see-through, so that it
    // does not hide the pressure on the body it touches
    var opacity = style.values && m.values === null && style.plain_opacity ? style.plain_opacity : style.opacity;
    var item = { mesh: m, pos: gl.createBuffer(), nrm: gl.createBuffer(), val: null, idx: gl.createBuffer(),
                 visible: style.visible, color: style.color, opacity: opacity, useLut: useLut };
    if (m.values !== null) {
      item.val = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, item.val);
      gl.bufferData(gl.ARRAY_BUFFER, m.values, gl.STATIC_DRAW);
    }
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, item.idx);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, m.triangles, gl.STATIC_DRAW);
    this.place(item);
    return item;
  };

  // positions = reference + scale * displacement, and their normals
  View.prototype.place = function (item) {
    var gl = this.gl, m = item.mesh, pos = new Float32Array(m.points.length);
    for (var i = 0; i < pos.length; i++) pos[i] = m.points[i] + this.scale * m.displacement[i];
    gl.bindBuffer(gl.ARRAY_BUFFER, item.pos);
    gl.bufferData(gl.ARRAY_BUFFER, pos, gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, item.nrm);
    gl.bufferData(gl.ARRAY_BUFFER, normals(pos, m.triangles), gl.DYNAMIC_DRAW);
  };

  View.prototype.reset = function () {
    this.target = this.box.center.slice();
    // the isometric view of the pictures (PyVista: from the +x +y +z octant), z up
    this.azimuth = Math.PI / 4; this.elevation = Math.atan(Math.SQRT1_2);
    this.dist = this.fit();
    this.draw();
  };

  // the camera distance at which the corners of the bounding box fill 90 % of the canvas
  View.prototype.fit = function () {
    var c = this.canvas, aspect = Math.max(c.clientWidth, 1) / Math.max(c.clientHeight, 1);
    var t = 0.9 * Math.tan(FOVY / 2), lo = this.box.lo, hi = this.box.hi, d = 0;
    this.dist = 1;
    var v = this.camera().view;  // the orientation only: its rows are the camera axes
    for (var i = 0; i < 8; i++) {
      var p = sub([i & 1 ? hi[0] : lo[0], i & 2 ? hi[1] : lo[1], i & 4 ? hi[2] : lo[2]], this.target);
      var x = v[0] * p[0] + v[4] * p[1] + v[8] * p[2], y = v[1] * p[0] + v[5] * p[1] + v[9] * p[2];
      var z = v[2] * p[0] + v[6] * p[1] + v[10] * p[2];  // towards the eye
      d = Math.max(d, z + Math.abs(y) / t, z + Math.abs(x) / (t * aspect));
    }
    return Math.max(d, 1e-6 * this.box.radius);
  };

  View.prototype.camera = function () {
    var ce = Math.cos(this.elevation), t = this.target, d = this.dist;
    var eye = [t[0] + d * ce * Math.cos(this.azimuth), t[1] + d * ce * Math.sin(this.azimuth),
               t[2] + d * Math.sin(this.elevation)];
    return { eye: eye, view: lookAt(eye, t, [0, 0, 1]) };
  };

  View.prototype.draw = function () {
    var self = this;
    if (this.pending) return;
    this.pending = true;
    window.requestAnimationFrame(function () { self.pending = false; self.render(); });
  };

  View.prototype.render = function () {
    var gl = this.gl, c = this.canvas, ratio = window.devicePixelRatio || 1;
    var w = Math.max(1, Math.round(c.clientWidth * ratio)), h = Math.max(1, Math.round(c.clientHeight * ratio));
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    gl.viewport(0, 0, w, h);
    gl.clearColor(0.965, 0.969, 0.976, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
        var cam = this.camera(), r = this.box.radius, L = this.loc;
    var near = Math.max(this.dist - 3 * r, this.dist * 1e-3), far = this.dist + 3 * r;
    var v = cam.view;
    gl.useProgram(L.prog);
    gl.uniformMatrix4fv(L.uView, false, new Float32Array(v));
    gl.uniformMatrix4fv(L.uProj, false, new Float32Array(perspective(FOVY, w / h, near, far)));
    gl.uniformMatrix3fv(L.uNormal, false, new Float32Array([v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]]));
    gl.uniform2f(L.uRange, this.scene.value_range[0], this.scene.value_range[1]);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, this.lut);
    gl.uniform1i(L.uLut, 0);
    var drawn = 0, self = this;
    var opaque = this.items.filter(function (it) { return it.visible && it.opacity >= 1; });
    var clear = this.items.filter(function (it) { return it.visible && it.opacity < 1; });
    gl.disable(gl.BLEND); gl.depthMask(true);
    opaque.forEach(function (it) { drawn += self.drawItem(it); });
    gl.enable(gl.BLEND); gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA); gl.depthMask(false);
    // translucent faces lying on opaque ones (the design domain's on the iso-surface's) stay behind them,
    // rather than flicker between in front and behind with the two triangulations
    gl.enable(gl.POLYGON_OFFSET_FILL); gl.polygonOffset(1, 4);
    clear.forEach(function (it) { drawn += self.drawItem(it); });
    gl.disable(gl.POLYGON_OFFSET_FILL); gl.depthMask(true);
    status.views[this.spec.id] = { triangles: drawn, width: w, height: h, scale: this.scale };
  };

  View.prototype.drawItem = function (it) {
    var gl = this.gl, L = this.loc, m = it.mesh;
    gl.bindBuffer(gl.ARRAY_BUFFER, it.pos);
    gl.enableVertexAttribArray(L.aPos);
    gl.vertexAttribPointer(L.aPos, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, it.nrm);
    gl.enableVertexAttribArray(L.aNormal);
    gl.vertexAttribPointer(L.aNormal, 3, gl.FLOAT, false, 0, 0);
    if (it.val && L.aValue >= 0) {
      gl.bindBuffer(gl.ARRAY_BUFFER, it.val);
      gl.enableVertexAttribArray(L.aValue);
      gl.vertexAttribPointer(L.aValue, 1, gl.FLOAT, false, 0, 0);
    } else if (L.aValue >= 0) {
      gl.disableVertexAttribArray(L.aValue);
      gl.vertexAttrib1f(L.aValue, 0.0);
    }
    gl.uniform3fv(L.uColor, it.color);
    gl.uniform1f(L.uOpacity, it.opacity);
    gl.uniform1f(L.uUseLut, it.useLut ? 1 : 0);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, it.idx);
    var n = m.triangles.length;
    gl.drawElements(gl.TRIANGLES, n, m.triangles instanceof Uint32Array ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT, 0);
    return n / 3;
  };

  View.prototype.controls = function () {
    var self = this, bar = document.createElement("div");
    bar.className = "cv-controls";
    this.items.forEach(function (it) {
      var label = document.createElement("label"), box = document.createElement("input");
      box.type = "checkbox";
      box.checked = it.visible;
      box.dataset.body = it.mesh.info.body;
      box.dataset.role = it.mesh.info.role;
      box.addEventListener("change", function () { it.visible = box.checked; self.draw(); });
      label.appendChild(box);
      label.appendChild(document.createTextNode(" " + it.mesh.info.label));
      bar.appendChild(label);
    });
    if (this.spec.deformed) {
      var label = document.createElement("label"), input = document.createElement("input");
      input.type = "number"; input.min = "0"; input.step = "0.5"; input.value = "1"; input.className = "cv-scale";
      input.addEventListener("change", function () {
        var s = parseFloat(input.value);
        if (!(s >= 0)) return;
        self.scale = s;
        self.items.forEach(function (it) { self.place(it); });
        self.draw();
      });
      label.appendChild(document.createTextNode("displacement \u00d7 "));
      label.appendChild(input);
      bar.appendChild(label);
    }
    var reset = document.createElement("button");
    reset.type = "button"; reset.textContent = "reset view";
    reset.addEventListener("click", function () { self.reset(); });
    bar.appendChild(reset);
    this.el.appendChild(bar);
  };

  View.prototype.mouse = function () {
    var self = this, c = this.canvas, last = null;
    c.addEventListener("contextmenu", function (e) { e.preventDefault(); });
    c.addEventListener("pointerdown", function (e) {
      last = { x: e.clientX, y: e.clientY, pan: e.button !== 0 || e.shiftKey };
      c.setPointerCapture(e.pointerId);
    });
    c.addEventListener("pointermove", function (e) {
      if (!last) return;
      var dx = e.clientX - last.x, dy = e.clientY - last.y;
      last.x = e.clientX; last.y = e.clientY;
      if (last.pan) {
        var v = self.camera().view, k = 2 * self.dist * Math.tan(FOVY / 2) / Math.max(c.clientHeight, 1);
        for (var i = 0; i < 3; i++) self.target[i] += k * (-dx * v[4 * i] + dy * v[4 * i + 1]);
      } else {
        self.azimuth -= 0.008 * dx;
        self.elevation = Math.max(-1.55, Math.min(1.55, self.elevation + 0.008 * dy));
      }
      self.draw();
    });
    function end(e) { last = null; if (c.hasPointerCapture(e.pointerId)) c.releasePointerCapture(e.pointerId); }
    c.addEventListener("pointerup", end);
    c.addEventListener("pointercancel", end);
    c.addEventListener("wheel", function (e) {
      e.preventDefault();
      self.dist *= Math.exp(0.0015 * Math.max(-300, Math.min(300, e.deltaY)));
      self.draw();
    }, { passive: false });
    c.addEventListener("dblclick", function () { self.reset(); });
  };

  function colourBar(el, scene) {
    var rgb = decode(scene.lut, Uint8Array), stops = [], n = rgb.length / 3;
    for (var i = 0; i < n; i += 15) stops.push("rgb(" + rgb[3 * i] + "," + rgb[3 * i + 1] + "," + rgb[3 * i + 2] + ")");
    stops.push("rgb(" + rgb[3 * n - 3] + "," + rgb[3 * n - 2] + "," + rgb[3 * n - 1] + ")");
    var bar = document.createElement("div"), ramp = document.createElement("div");
    var ticks = document.createElement("div");
    bar.className = "cv-colourbar";
    ramp.className = "cv-ramp";
    ramp.style.background = "linear-gradient(to right, " + stops.join(", ") + ")";
    ticks.className = "cv-ticks";
    var lo = scene.value_range[0], hi = scene.value_range[1];
    [0, 0.25, 0.5, 0.75, 1].forEach(function (f) {
      var s = document.createElement("span");
      s.textContent = Number((lo + f * (hi - lo)).toPrecision(3)).toString();
      ticks.appendChild(s);
    });
    var title = document.createElement("div");
    title.className = "cv-bar-title";
    title.textContent = scene.value_label;
    bar.appendChild(title); bar.appendChild(ramp); bar.appendChild(ticks);
    el.appendChild(bar);
  }

  function start() {
    var node = document.getElementById("contopt-scene");
    if (!node) { status.ready = true; return; }
    var scene;
    try {
      scene = JSON.parse(node.textContent);
    } catch (err) { fail("the embedded scene does not parse: " + err.message); return; }
    var meshes = scene.meshes.map(decodeMesh), box = bounds(meshes);
    scene.views.forEach(function (spec) {
      var el = document.querySelector('.cv-view[data-view="' + spec.id + '"]');
      if (!el) return;
      try {
        var view = new View(el, scene, meshes, spec, box);
        if (spec.colour_by_values) colourBar(el, scene);
        view.render();
      } catch (err) { fail(err.message, el); }
    });
    status.ready = true;
  }

  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", start);
  else start();
})();

// sieve-mi report page: a small WebGL viewer of the passage and a zoomable 2D hole view.
// No third-party code and no requests: the scene is the JSON in #sieve-data.
"use strict";
(function () {
  var errors = [];
  function fail(msg) {
    errors.push(String(msg));
    var el = document.getElementById("errors");
    el.textContent = errors.join("\n");
    el.hidden = false;
    document.body.setAttribute("data-errors", String(errors.length));
  }
  window.addEventListener("error", function (e) {
    var t = e.target;
    fail(e.message || ("could not load " + (t && (t.src || t.href) || "a resource")));
  }, true);
  window.addEventListener("unhandledrejection", function (e) { fail("unhandled: " + e.reason); });
  document.addEventListener("securitypolicyviolation", function (e) { fail("blocked request: " + e.blockedURI); });

  // Drawn: say so, and whether the layout fits the window's width (no sideways scrolling).
  function ready() {
    var root = document.documentElement;
    document.body.setAttribute("data-fits", root.scrollWidth <= root.clientWidth ? "1" : "0");
    document.body.setAttribute("data-ready", "1");
  }
  var dataEl = document.getElementById("sieve-data");
  if (!dataEl) {  // the page of sieve-mi check: only the 2D view
    try { holeControls(); } catch (e) { fail(e && e.stack ? e.stack : e); }
    ready();
    return;
  }
  var data = JSON.parse(dataEl.textContent);
  var opts = parseHash(location.hash);
  var hidden = {};
  if (opts.show !== undefined) {
    var keep = opts.show.split(",");
    hidden.plate = keep.indexOf("plate") < 0;
    data.pieces.forEach(function (p) { hidden[p.id] = keep.indexOf(p.id) < 0; });
  }
  if (opts.full !== undefined) document.body.classList.add("full");

  function parseHash(h) {
    var out = {};
    h.replace(/^#/, "").split("&").forEach(function (kv) {
      if (!kv) return;
      var i = kv.indexOf("=");
      out[decodeURIComponent(i < 0 ? kv : kv.slice(0, i))] = i < 0 ? "" : decodeURIComponent(kv.slice(i + 1));
    });
    return out;
  }

  function decode(b64, Type) {
    var s = atob(b64), bytes = new Uint8Array(s.length);
    for (var i = 0; i < s.length; i++) bytes[i] = s.charCodeAt(i);
    return new Type(bytes.buffer);
  }

  // ---- matrices (column-major, as WebGL wants) ----
  function mul(a, b) {
    var o = new Float32Array(16);
    for (var c = 0; c < 4; c++) for (var r = 0; r < 4; r++) {
      var s = 0;
      for (var k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
      o[c * 4 + r] = s;
    }
    return o;
  }
  function perspective(fovy, aspect, near, far) {
    var f = 1 / Math.tan(fovy / 2), o = new Float32Array(16);
    o[0] = f / aspect; o[5] = f; o[10] = (far + near) / (near - far); o[11] = -1;
    o[14] = 2 * far * near / (near - far);
    return o;
  }
  function ortho(hw, hh, near, far) {
    var o = new Float32Array(16);
    o[0] = 1 / hw; o[5] = 1 / hh; o[10] = -2 / (far - near); o[14] = -(far + near) / (far - near); o[15] = 1;
    return o;
  }
  function lookAt(eye, target, up) {
    var z = norm(sub(eye, target)), x = norm(cross(up, z)), y = cross(z, x), o = new Float32Array(16);
    o[0] = x[0]; o[4] = x[1]; o[8] = x[2];
    o[1] = y[0]; o[5] = y[1]; o[9] = y[2];
    o[2] = z[0]; o[6] = z[1]; o[10] = z[2];
    o[12] = -dot(x, eye); o[13] = -dot(y, eye); o[14] = -dot(z, eye); o[15] = 1;
    return o;
  }
  function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
  function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
  function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
  function norm(a) { var l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; }

  // ---- the motion (as sieve_mi.outputs.passage.Piece.offset) ----
  function offset(p, s) {
    var u = (s - p.slot[0]) / (p.slot[1] - p.slot[0]);
    var f = p.stop > 0 ? Math.min(Math.max(u, 0), p.stop) / p.stop : 1;
    return p.start + f * (p.end - p.start);
  }
  // a thin-plate passage follows its keys (u, quaternion w x y z, translation), as Piece.matrix
  function slerp(a, b, f) {
    var d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3], s = d < 0 ? -1 : 1;
    d = Math.abs(d);
    var w = Math.acos(Math.min(1, d)), k0 = 1 - f, k1 = f;
    if (d < 1 - 1e-12) { k0 = Math.sin((1 - f) * w) / Math.sin(w); k1 = Math.sin(f * w) / Math.sin(w); }
    var q = [0, 1, 2, 3].map(function (i) { return k0 * a[i] + s * k1 * b[i]; });
    var l = Math.hypot(q[0], q[1], q[2], q[3]) || 1;
    return q.map(function (x) { return x / l; });
  }
  function place(p, s) {
    if (!p.keys) return { rot: [1, 0, 0, 0, 1, 0, 0, 0, 1], shift: [0, 0, offset(p, s)] };
    var u = Math.min(Math.max((s - p.slot[0]) / (p.slot[1] - p.slot[0]), 0), 1), k = 0;
    while (k < p.keys.length - 2 && p.keys[k + 1][0] <= u) k++;
    var a = p.keys[k], b = p.keys[k + 1], f = b[0] > a[0] ? (u - a[0]) / (b[0] - a[0]) : 0;
    var q = slerp(a.slice(1, 5), b.slice(1, 5), f), w = q[0], x = q[1], y = q[2], z = q[3];
    var t = [0, 1, 2].map(function (i) { return (1 - f) * a[5 + i] + f * b[5 + i]; });
    // column-major 3x3 rotation of the quaternion
    return { rot: [1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y),
      2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x),
      2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], shift: t };
  }
  function visible(p, s) { return (p.slot[0] <= s && s < p.slot[1]) || (p.slot[1] >= 1 && s >= 1); }

  // ---- WebGL ----
  var canvas = document.getElementById("gl");
  var gl = null;
  try { gl = canvas.getContext("webgl", { antialias: true, preserveDrawingBuffer: true }); } catch (e) { gl = null; }
  var bounds = data.bounds, centre = [0, 1, 2].map(function (i) { return (bounds[0][i] + bounds[1][i]) / 2; });
  var radius = 0.5 * Math.hypot(bounds[1][0] - bounds[0][0], bounds[1][1] - bounds[0][1], bounds[1][2] - bounds[0][2]);
  var cam = {};
  var DIST = 2.6 * radius;  // the initial distance; the top view's zoom is relative to it
  function resetCamera() { cam.yaw = -1.05; cam.pitch = 0.42; cam.dist = DIST; cam.top = false; }
  resetCamera();
  if (opts.view === "top") cam.top = true;
  var phase = opts.t !== undefined ? Math.min(Math.max(parseFloat(opts.t) || 0, 0), 1) : 0;
  var playing = opts.t === undefined;
  var meshes = [], program = null, xray = false;

  function shader(type, src) {
    var s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  function setupGL() {
    program = gl.createProgram();
    gl.attachShader(program, shader(gl.VERTEX_SHADER,
      "attribute vec3 p; attribute vec3 n; uniform mat4 mvp; uniform mat3 rot; uniform vec3 shift; varying vec3 vn;" +
      "void main() { vn = rot * n; gl_Position = mvp * vec4(rot * p + shift, 1.0); }"));
    gl.attachShader(program, shader(gl.FRAGMENT_SHADER,
      "precision mediump float; uniform vec3 colour; uniform vec3 light; uniform float alpha; varying vec3 vn;" +
      "void main() { float d = abs(dot(normalize(vn), light)); gl_FragColor = vec4(colour * (0.42 + 0.58 * d), alpha); }"));
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
    meshes.push(upload("plate", data.plate, null));
    data.pieces.forEach(function (p) { meshes.push(upload(p.id, p, p)); });
  }
  // Flat shading: every triangle gets its own three corners and its face normal.
  function upload(id, m, piece) {
    var v = decode(m.positions, Float32Array), f = decode(m.faces, Uint32Array);
    var pos = new Float32Array(f.length * 3), nrm = new Float32Array(f.length * 3);
    for (var t = 0; t < f.length; t += 3) {
      var a = f[t] * 3, b = f[t + 1] * 3, c = f[t + 2] * 3;
      var e1 = [v[b] - v[a], v[b + 1] - v[a + 1], v[b + 2] - v[a + 2]];
      var e2 = [v[c] - v[a], v[c + 1] - v[a + 1], v[c + 2] - v[a + 2]];
      var n = norm(cross(e1, e2));
      [a, b, c].forEach(function (k, j) {
        for (var i = 0; i < 3; i++) { pos[(t + j) * 3 + i] = v[k + i]; nrm[(t + j) * 3 + i] = n[i]; }
      });
    }
    var pb = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, pb); gl.bufferData(gl.ARRAY_BUFFER, pos, gl.STATIC_DRAW);
    var nb = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, nb); gl.bufferData(gl.ARRAY_BUFFER, nrm, gl.STATIC_DRAW);
    return { id: id, pos: pb, nrm: nb, count: f.length, colour: m.colour, piece: piece };
  }

  function viewProjection(w, h) {
    var aspect = w / h;
    if (cam.top) {
      var box = data.plate_box, cx = (box[0][0] + box[1][0]) / 2, cy = (box[0][1] + box[1][1]) / 2;
      var half = 0.5 * Math.max(box[1][0] - box[0][0], box[1][1] - box[0][1]) * cam.dist / DIST;
      var hw = aspect >= 1 ? half * aspect : half, hh = aspect >= 1 ? half : half / aspect;
      var top = bounds[1][2] + radius;
      return mul(ortho(hw, hh, 0.001 * radius, 4 * radius + top - bounds[0][2]),
        lookAt([cx, cy, top], [cx, cy, bounds[0][2]], [0, 1, 0]));
    }
    var cp = Math.cos(cam.pitch);
    var eye = [centre[0] + cam.dist * cp * Math.cos(cam.yaw), centre[1] + cam.dist * cp * Math.sin(cam.yaw),
      centre[2] + cam.dist * Math.sin(cam.pitch)];
    return mul(perspective(0.7, aspect, 0.01 * radius, cam.dist + 4 * radius), lookAt(eye, centre, [0, 0, 1]));
  }

  function draw() {
    var dpr = window.devicePixelRatio || 1;
    var w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    gl.viewport(0, 0, w, h);
    var bg = data.background;
    gl.clearColor(bg[0], bg[1], bg[2], 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    gl.useProgram(program);
    var mvp = viewProjection(w, h);
    gl.uniformMatrix4fv(gl.getUniformLocation(program, "mvp"), false, mvp);
    gl.uniform3fv(gl.getUniformLocation(program, "light"), norm([0.35, -0.45, 0.82]));
    var order = meshes.slice(1).concat([meshes[0]]);  // the plate last: it may be see-through
    order.forEach(function (m) {
      if (hidden[m.id] || (m.piece && !visible(m.piece, phase))) return;
      var see = xray && m.id === "plate";
      gl.depthMask(!see);
      if (see) { gl.enable(gl.BLEND); gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA); } else gl.disable(gl.BLEND);
      var pose = m.piece ? place(m.piece, phase) : { rot: [1, 0, 0, 0, 1, 0, 0, 0, 1], shift: [0, 0, 0] };
      gl.uniformMatrix3fv(gl.getUniformLocation(program, "rot"), false, pose.rot);
      gl.uniform3fv(gl.getUniformLocation(program, "shift"), pose.shift);
      gl.uniform3fv(gl.getUniformLocation(program, "colour"), m.colour);
      gl.uniform1f(gl.getUniformLocation(program, "alpha"), see ? 0.35 : 1.0);
      bindAttr("p", m.pos); bindAttr("n", m.nrm);
      gl.drawArrays(gl.TRIANGLES, 0, m.count);
    });
    gl.depthMask(true);
  }
  function bindAttr(name, buffer) {
    var loc = gl.getAttribLocation(program, name);
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
  }

  var slider = document.getElementById("phase"), playBtn = document.getElementById("play");
  var last = null, PERIOD = 3000 * (data.pieces.filter(function (p) { return p.role === "block"; }).length + 1), HOLD = 0.1, clock = 0;
  function frame(now) {
    if (playing) {
      if (last !== null) clock = (clock + (now - last)) % (PERIOD * (1 + HOLD));
      phase = Math.min(clock / PERIOD, 1);
      slider.value = String(Math.round(phase * 1000));
    }
    last = now;
    draw();
    if (!document.body.hasAttribute("data-ready")) ready();
    requestAnimationFrame(frame);
  }

  function orbitControls() {
    var pointers = {}, pinch = null;
    canvas.addEventListener("pointerdown", function (e) { canvas.setPointerCapture(e.pointerId); pointers[e.pointerId] = [e.clientX, e.clientY]; pinch = null; });
    canvas.addEventListener("pointermove", function (e) {
      var old = pointers[e.pointerId];
      if (!old) return;
      var ids = Object.keys(pointers);
      pointers[e.pointerId] = [e.clientX, e.clientY];
      if (ids.length === 1) {
        cam.top = false;
        cam.yaw -= (e.clientX - old[0]) * 0.01;
        cam.pitch = Math.min(1.5, Math.max(-1.5, cam.pitch + (e.clientY - old[1]) * 0.01));
      } else if (ids.length === 2) {
        var a = pointers[ids[0]], b = pointers[ids[1]], d = Math.hypot(a[0] - b[0], a[1] - b[1]);
        if (pinch) zoom(pinch / d);
        pinch = d;
      }
    });
    function up(e) { delete pointers[e.pointerId]; pinch = null; }
    canvas.addEventListener("pointerup", up);
    canvas.addEventListener("pointercancel", up);
    canvas.addEventListener("wheel", function (e) { e.preventDefault(); zoom(Math.exp(e.deltaY * 0.001)); }, { passive: false });
  }
  function zoom(k) { cam.dist = Math.min(20 * radius, Math.max(0.3 * radius, cam.dist * k)); }

  function controls() {
    playBtn.textContent = playing ? "pause" : "play";
    playBtn.addEventListener("click", function () {
      playing = !playing; last = null; clock = phase * PERIOD;
      playBtn.textContent = playing ? "pause" : "play";
    });
    slider.value = String(Math.round(phase * 1000));
    slider.addEventListener("input", function () {
      playing = false; playBtn.textContent = "play"; phase = slider.value / 1000;
    });
    document.getElementById("reset3d").addEventListener("click", resetCamera);
    document.getElementById("top3d").addEventListener("click", function () { cam.top = true; });
    document.getElementById("xray").addEventListener("change", function (e) { xray = e.target.checked; });
    Array.prototype.forEach.call(document.querySelectorAll("[data-toggle]"), function (box) {
      var id = box.getAttribute("data-toggle");
      box.checked = !hidden[id];
      box.addEventListener("change", function () { hidden[id] = !box.checked; show2d(); });
    });
    show2d();
  }
  function show2d() {
    Array.prototype.forEach.call(document.querySelectorAll("#hole2d [data-id]"), function (el) {
      var id = el.getAttribute("data-id");
      el.style.display = hidden[id] ? "none" : "";
    });
  }

  // ---- the 2D hole: zoom (wheel, pinch, buttons) and pan (drag) of the SVG's viewBox ----
  function holeControls() {
    var svg = document.getElementById("hole2d");
    if (!svg) return;
    var lim = parseFloat(svg.getAttribute("data-lim")), vb = null;
    function reset() { vb = [-lim, -lim, 2 * lim, 2 * lim]; apply(); }
    function apply() { svg.setAttribute("viewBox", vb.join(" ")); }
    function toUser(x, y) {
      var r = svg.getBoundingClientRect(), s = Math.max(vb[2] / r.width, vb[3] / r.height);
      return [vb[0] + vb[2] / 2 + (x - r.left - r.width / 2) * s, vb[1] + vb[3] / 2 + (y - r.top - r.height / 2) * s, s];
    }
    function zoomAt(k, x, y) {
      var c = x === undefined ? [vb[0] + vb[2] / 2, vb[1] + vb[3] / 2] : toUser(x, y);
      k = Math.min(Math.max(k, 1e-3 * lim / vb[2]), 4 * lim / vb[2]);
      vb = [c[0] - (c[0] - vb[0]) * k, c[1] - (c[1] - vb[1]) * k, vb[2] * k, vb[3] * k];
      apply();
    }
    var pointers = {}, pinch = null;
    svg.addEventListener("wheel", function (e) { e.preventDefault(); zoomAt(Math.exp(e.deltaY * 0.001), e.clientX, e.clientY); }, { passive: false });
    svg.addEventListener("pointerdown", function (e) { svg.setPointerCapture(e.pointerId); pointers[e.pointerId] = [e.clientX, e.clientY]; pinch = null; });
    svg.addEventListener("pointermove", function (e) {
      var old = pointers[e.pointerId];
      if (!old) return;
      pointers[e.pointerId] = [e.clientX, e.clientY];
      var ids = Object.keys(pointers);
      if (ids.length === 1) {
        var s = toUser(0, 0)[2];
        vb[0] -= (e.clientX - old[0]) * s; vb[1] -= (e.clientY - old[1]) * s; apply();
      } else if (ids.length === 2) {
        var a = pointers[ids[0]], b = pointers[ids[1]], d = Math.hypot(a[0] - b[0], a[1] - b[1]);
        if (pinch) zoomAt(pinch / d, (a[0] + b[0]) / 2, (a[1] + b[1]) / 2);
        pinch = d;
      }
    });
    function up(e) { delete pointers[e.pointerId]; pinch = null; }
    svg.addEventListener("pointerup", up);
    svg.addEventListener("pointercancel", up);
    document.getElementById("zoomin").addEventListener("click", function () { zoomAt(0.7); });
    document.getElementById("zoomout").addEventListener("click", function () { zoomAt(1 / 0.7); });
    document.getElementById("reset2d").addEventListener("click", reset);
    reset();
  }

  try {
    controls();
    holeControls();
    if (!gl) {
      document.getElementById("nogl").hidden = false;
      canvas.hidden = true;
      document.body.setAttribute("data-webgl", "none");
      ready();
    } else {
      setupGL();
      orbitControls();
      frame(performance.now());  // the first frame now, not on a timer: the page is drawn (and ready) when the script ends
    }
  } catch (e) {
    fail(e && e.stack ? e.stack : e);
  }
})();

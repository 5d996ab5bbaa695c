/* flexmor 3D viewer: a small WebGL program for the report and the web app (no library, offline).
 * Scene JSON from flexmor.report.view3d: vertices (float64), triangles/lines (uint32), marks,
 * spiders, and shapes (int16 scaled by "amp", real and imaginary parts) at the vertices. */
"use strict";
var FlexmorView = (function () {
  var MARK_COLORS = {inputs: [0.85, 0.1, 0.1], outputs: [0.1, 0.35, 0.9], interface: [0.0, 0.65, 0.2],
                     masters: [0.6, 0.0, 0.75], selection: [1.0, 0.55, 0.0]};
  var MARK_SIZES = {inputs: 14, interface: 11, masters: 8, outputs: 5, selection: 7};

  function bytes(s) {
    var bin = atob(s), out = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out.buffer;
  }
  function decodeShape(item, n) {
    var f = item.amp / 32767, re = new Int16Array(bytes(item.re)), r = new Float32Array(3 * n);
    for (var i = 0; i < r.length; i++) r[i] = re[i] * f;
    var im = null;
    if (item.im) {
      var ii = new Int16Array(bytes(item.im));
      im = new Float32Array(3 * n);
      for (var k = 0; k < im.length; k++) im[k] = ii[k] * f;
    }
    return {re: r, im: im, amp: item.amp};
  }
  function decodeBody(scene) {
    return {xyz: new Float64Array(bytes(scene.xyz)), tris: new Uint32Array(bytes(scene.tris)),
            lines: new Uint32Array(bytes(scene.lines)), n: scene.n_vertices, marks: scene.marks || {},
            spiders: scene.spiders || [], ids: scene.node_ids || []};
  }
  function colormap(t) {  // blue - cyan - green - yellow - red
    var stops = [[0.19, 0.3, 0.85], [0.1, 0.75, 0.9], [0.2, 0.8, 0.3], [0.95, 0.85, 0.15], [0.9, 0.15, 0.1]];
    t = Math.max(0, Math.min(1, t)) * 4;
    var i = Math.min(3, Math.floor(t)), u = t - i, a = stops[i], b = stops[i + 1];
    return [a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2])];
  }
  // -- small matrix helpers (column-major 4x4 as WebGL expects) --
  function mul(a, b) {
    var r = new Float32Array(16);
    for (var i = 0; i < 4; i++) for (var j = 0; j < 4; j++) {
      var s = 0; for (var k = 0; k < 4; k++) s += a[k * 4 + j] * b[i * 4 + k]; r[i * 4 + j] = s;
    }
    return r;
  }
  function rotX(a) { var c = Math.cos(a), s = Math.sin(a); return new Float32Array([1,0,0,0, 0,c,s,0, 0,-s,c,0, 0,0,0,1]); }
  function rotY(a) { var c = Math.cos(a), s = Math.sin(a); return new Float32Array([c,0,-s,0, 0,1,0,0, s,0,c,0, 0,0,0,1]); }
  function rotZ(a) { var c = Math.cos(a), s = Math.sin(a); return new Float32Array([c,s,0,0, -s,c,0,0, 0,0,1,0, 0,0,0,1]); }
  function trans(x, y, z) { return new Float32Array([1,0,0,0, 0,1,0,0, 0,0,1,0, x,y,z,1]); }
  function persp(fov, asp, n, f) {
    var t = 1 / Math.tan(fov / 2);
    return new Float32Array([t / asp,0,0,0, 0,t,0,0, 0,0,(f + n) / (n - f),-1, 0,0,2 * f * n / (n - f),0]);
  }
  var VS_TRI = "attribute vec3 p;attribute vec3 nrm;attribute vec3 col;uniform mat4 mvp;uniform mat4 rot;" +
    "varying vec3 vc;varying float lit;void main(){gl_Position=mvp*vec4(p,1.0);" +
    "vec3 nv=normalize((rot*vec4(nrm,0.0)).xyz);lit=0.35+0.65*abs(nv.z);vc=col;}";
  var FS_TRI = "precision mediump float;varying vec3 vc;varying float lit;void main(){gl_FragColor=vec4(vc*lit,1.0);}";
  var VS_PT = "attribute vec3 p;attribute vec3 col;uniform mat4 mvp;uniform float ps;varying vec3 vc;" +
    "void main(){gl_Position=mvp*vec4(p,1.0);gl_PointSize=ps;vc=col;}";
  var FS_PT = "precision mediump float;varying vec3 vc;void main(){gl_FragColor=vec4(vc,1.0);}";

  function program(gl, vs, fs) {
    function sh(type, src) {
      var s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
      return s;
    }
    var p = gl.createProgram();
    gl.attachShader(p, sh(gl.VERTEX_SHADER, vs)); gl.attachShader(p, sh(gl.FRAGMENT_SHADER, fs));
    gl.linkProgram(p);
    return p;
  }

  /* One canvas showing the body; cameras of several viewers can be linked (shared `cam`). */
  function Viewer(canvas, body, cam) {
    this.canvas = canvas; this.body = body; this.shape = null; this.scale = 0.1; this.phase = 0;
    this.selected = []; this.onBox = null; this.listeners = [];
    var gl = canvas.getContext("webgl", {preserveDrawingBuffer: true, antialias: true});
    if (!gl) throw new Error("WebGL is not available in this browser");
    this.gl = gl;
    gl.getExtension("OES_element_index_uint");
    this.ptri = program(gl, VS_TRI, FS_TRI); this.ppt = program(gl, VS_PT, FS_PT);
    this.buf = {p: gl.createBuffer(), n: gl.createBuffer(), c: gl.createBuffer(), t: gl.createBuffer(),
                l: gl.createBuffer(), mp: gl.createBuffer(), mc: gl.createBuffer()};
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buf.t); gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, body.tris, gl.STATIC_DRAW);
    var x = body.xyz, lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    var pts = [x];
    Object.keys(body.marks).forEach(function (k) { pts.push(new Float32Array([].concat.apply([], body.marks[k]))); });
    pts.forEach(function (a) {
      for (var i = 0; i < a.length; i += 3) for (var d = 0; d < 3; d++) {
        lo[d] = Math.min(lo[d], a[i + d]); hi[d] = Math.max(hi[d], a[i + d]);
      }
    });
    this.center = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2];
    this.radius = Math.max(1e-12, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
    this.cam = cam || {rot: mul(rotX(-1.1), rotZ(-0.6)), dist: 3.2, pan: [0, 0], views: []};
    this.cam.views.push(this);
    this._mouse();
  }
  Viewer.prototype.setShape = function (shape) { this.shape = shape; this.draw(); };
  Viewer.prototype.matrices = function () {
    var c = this.canvas, w = c.clientWidth || 400, h = c.clientHeight || 300, r = this.radius, cam = this.cam;
    var model = mul(trans(cam.pan[0] * r, cam.pan[1] * r, -cam.dist * r),
                    mul(cam.rot, trans(-this.center[0], -this.center[1], -this.center[2])));
    return {mvp: mul(persp(0.55, w / h, r * 0.05, r * 50), model), rot: cam.rot, w: w, h: h};
  };
  Viewer.prototype.positions = function () {
    var x = this.body.xyz, n = this.body.n, out = new Float32Array(3 * n), col = new Float32Array(3 * n);
    var s = this.shape, c = Math.cos(this.phase), sn = Math.sin(this.phase);
    if (!s) {
      out.set(x);
      for (var i = 0; i < n; i++) { col[3 * i] = 0.72; col[3 * i + 1] = 0.74; col[3 * i + 2] = 0.78; }
      return {p: out, c: col};
    }
    var f = this.scale * this.radius / (s.amp > 0 ? maxNorm(s) : 1), mag = new Float32Array(n), mx = 0;
    for (var v = 0; v < n; v++) {
      var m2 = 0;
      for (var d = 0; d < 3; d++) {
        var k = 3 * v + d, re = s.re[k], im = s.im ? s.im[k] : 0;
        out[k] = x[k] + f * (re * c - im * sn);
        m2 += re * re + im * im;
      }
      mag[v] = Math.sqrt(m2); mx = Math.max(mx, mag[v]);
    }
    for (var u = 0; u < n; u++) { var cc = colormap(mx > 0 ? mag[u] / mx : 0); col.set(cc, 3 * u); }
    return {p: out, c: col};
  };
  function maxNorm(s) {
    if (s._max !== undefined) return s._max;
    var mx = 0;
    for (var v = 0; v < s.re.length; v += 3) {
      var m2 = 0;
      for (var d = 0; d < 3; d++) { var re = s.re[v + d], im = s.im ? s.im[v + d] : 0; m2 += re * re + im * im; }
      mx = Math.max(mx, m2);
    }
    s._max = Math.sqrt(mx) || 1;
    return s._max;
  }
  function normals(p, t, n) {
    var nr = new Float32Array(3 * n);
    for (var i = 0; i < t.length; i += 3) {
      var a = 3 * t[i], b = 3 * t[i + 1], c = 3 * t[i + 2];
      var ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
      var vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
      var nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
      // two-sided lighting in the shader: orient every face the same way for smoothing
      [a, b, c].forEach(function (q) { nr[q] += nx; nr[q + 1] += ny; nr[q + 2] += nz; });
    }
    return nr;
  }
  Viewer.prototype.draw = function () {
    var gl = this.gl, c = this.canvas, dpr = window.devicePixelRatio || 1;
    var w = Math.max(1, Math.round((c.clientWidth || 400) * dpr)), h = Math.max(1, Math.round((c.clientHeight || 300) * dpr));
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    gl.viewport(0, 0, w, h);
    gl.clearColor(1, 1, 1, 1); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    var m = this.matrices(), pc = this.positions(), b = this.body, self = this;
    function attr(prog, name, buf, data) {
      var loc = gl.getAttribLocation(prog, name);
      if (loc < 0) return;
      gl.bindBuffer(gl.ARRAY_BUFFER, buf); gl.bufferData(gl.ARRAY_BUFFER, data, gl.DYNAMIC_DRAW);
      gl.enableVertexAttribArray(loc); gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
    }
    if (b.tris.length) {
      gl.useProgram(this.ptri);
      gl.uniformMatrix4fv(gl.getUniformLocation(this.ptri, "mvp"), false, m.mvp);
      gl.uniformMatrix4fv(gl.getUniformLocation(this.ptri, "rot"), false, m.rot);
      attr(this.ptri, "p", this.buf.p, pc.p); attr(this.ptri, "nrm", this.buf.n, normals(pc.p, b.tris, b.n));
      attr(this.ptri, "col", this.buf.c, pc.c);
      gl.enable(gl.POLYGON_OFFSET_FILL); gl.polygonOffset(1, 1);
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buf.t);
      gl.drawElements(gl.TRIANGLES, b.tris.length, gl.UNSIGNED_INT, 0);
      gl.disable(gl.POLYGON_OFFSET_FILL);
    }
    gl.useProgram(this.ppt);
    gl.uniformMatrix4fv(gl.getUniformLocation(this.ppt, "mvp"), false, m.mvp);
    var psLoc = gl.getUniformLocation(this.ppt, "ps");
    if (b.lines.length) {  // beams (and the surface's own segments), deformed
      var lp = new Float32Array(3 * b.lines.length), lc = new Float32Array(3 * b.lines.length);
      for (var i = 0; i < b.lines.length; i++) { lp.set(pc.p.subarray(3 * b.lines[i], 3 * b.lines[i] + 3), 3 * i); lc.set(pc.c.subarray(3 * b.lines[i], 3 * b.lines[i] + 3), 3 * i); }
      attr(this.ppt, "p", this.buf.mp, lp); attr(this.ppt, "col", this.buf.mc, lc);
      gl.drawArrays(gl.LINES, 0, b.lines.length);
    }
    if (!b.tris.length && !b.lines.length) {  // no elements: the nodes as points
      gl.uniform1f(psLoc, 3 * dpr);
      attr(this.ppt, "p", this.buf.mp, pc.p); attr(this.ppt, "col", this.buf.mc, pc.c);
      gl.drawArrays(gl.POINTS, 0, b.n);
    }
    // spiders and marks, undeformed, drawn over the surface
    gl.disable(gl.DEPTH_TEST);
    var sp = [], sc = [];
    b.spiders.forEach(function (s) { sp.push.apply(sp, s[0]); sp.push.apply(sp, s[1]); sc.push(0.6, 0, 0.75, 0.6, 0, 0.75); });
    if (sp.length) {
      attr(this.ppt, "p", this.buf.mp, new Float32Array(sp)); attr(this.ppt, "col", this.buf.mc, new Float32Array(sc));
      gl.drawArrays(gl.LINES, 0, sp.length / 3);
    }
    var marks = Object.assign({}, b.marks), self2 = this;
    if (this.selected.length) marks.selection = this.selected;
    var kinds = Object.keys(marks).sort(function (a, b) { return (MARK_SIZES[b] || 7) - (MARK_SIZES[a] || 7); });
    kinds.forEach(function (k) {  // largest first, one call per kind: coinciding kinds show as rings
      var mp = [], mc = [];
      marks[k].forEach(function (q) { mp.push(q[0], q[1], q[2]); mc.push.apply(mc, MARK_COLORS[k] || [0, 0, 0]); });
      if (!mp.length) return;
      gl.uniform1f(psLoc, (MARK_SIZES[k] || 7) * dpr);
      attr(self2.ppt, "p", self2.buf.mp, new Float32Array(mp)); attr(self2.ppt, "col", self2.buf.mc, new Float32Array(mc));
      gl.drawArrays(gl.POINTS, 0, mp.length / 3);
    });
    this.listeners.forEach(function (f) { f(self); });
  };
  Viewer.prototype.redrawAll = function () { this.cam.views.forEach(function (v) { v.draw(); }); };
  /* Screen positions (CSS pixels) of the vertices, for box selection. */
  Viewer.prototype.project = function () {
    var m = this.matrices(), x = this.body.xyz, n = this.body.n, out = new Float32Array(2 * n), M = m.mvp;
    for (var v = 0; v < n; v++) {
      var X = x[3 * v], Y = x[3 * v + 1], Z = x[3 * v + 2];
      var cx = M[0] * X + M[4] * Y + M[8] * Z + M[12], cy = M[1] * X + M[5] * Y + M[9] * Z + M[13];
      var cw = M[3] * X + M[7] * Y + M[11] * Z + M[15];
      out[2 * v] = (cx / cw + 1) / 2 * m.w; out[2 * v + 1] = (1 - cy / cw) / 2 * m.h;
    }
    return out;
  };
  Viewer.prototype.boxSelect = function (x0, y0, x1, y1) {
    var p = this.project(), idx = [];
    var ax = Math.min(x0, x1), bx = Math.max(x0, x1), ay = Math.min(y0, y1), by = Math.max(y0, y1);
    for (var v = 0; v < this.body.n; v++) {
      if (p[2 * v] >= ax && p[2 * v] <= bx && p[2 * v + 1] >= ay && p[2 * v + 1] <= by) idx.push(v);
    }
    return idx;
  };
  Viewer.prototype._mouse = function () {
    var self = this, c = this.canvas, last = null, box = null, rect = null;
    c.addEventListener("contextmenu", function (e) { e.preventDefault(); });
    c.addEventListener("pointerdown", function (e) {
      last = {x: e.clientX, y: e.clientY, b: e.button, shift: e.shiftKey};
      if (e.shiftKey && self.onBox) {
        var r = c.getBoundingClientRect();
        box = {x0: e.clientX - r.left, y0: e.clientY - r.top};
        rect = document.createElement("div");
        rect.style.cssText = "position:fixed;border:1px dashed #e60;background:rgba(255,140,0,0.12);pointer-events:none";
        document.body.appendChild(rect);
      }
      if (c.setPointerCapture) c.setPointerCapture(e.pointerId);
    });
    c.addEventListener("pointermove", function (e) {
      if (!last) return;
      var dx = e.clientX - last.x, dy = e.clientY - last.y;
      if (box) {
        rect.style.left = Math.min(e.clientX, last.x) + "px"; rect.style.top = Math.min(e.clientY, last.y) + "px";
        rect.style.width = Math.abs(dx) + "px"; rect.style.height = Math.abs(dy) + "px";
        return;
      }
      var cam = self.cam;
      if (last.b === 2 || last.b === 1) { cam.pan[0] += dx / c.clientWidth * cam.dist * 0.9; cam.pan[1] -= dy / c.clientHeight * cam.dist * 0.9; }
      else cam.rot = mul(rotX(dy * 0.01), mul(rotY(dx * 0.01), cam.rot));
      last.x = e.clientX; last.y = e.clientY;
      self.redrawAll();
    });
    c.addEventListener("pointerup", function (e) {
      if (box) {
        var r = c.getBoundingClientRect();
        var x1 = e.clientX - r.left, y1 = e.clientY - r.top, idx;
        var click = Math.abs(x1 - box.x0) < 4 && Math.abs(y1 - box.y0) < 4;
        if (click) {  // a shift+click: the nearest vertex within 10 px
          var p = self.project(), best = -1, d2 = 100;
          for (var v = 0; v < self.body.n; v++) {
            var q = (p[2 * v] - x1) * (p[2 * v] - x1) + (p[2 * v + 1] - y1) * (p[2 * v + 1] - y1);
            if (q < d2) { d2 = q; best = v; }
          }
          idx = best < 0 ? [] : [best];
        } else idx = self.boxSelect(box.x0, box.y0, x1, y1);
        document.body.removeChild(rect); rect = null; box = null;
        self.onBox(idx, click);
      }
      last = null;
    });
    c.addEventListener("wheel", function (e) {
      e.preventDefault(); self.cam.dist *= Math.exp(e.deltaY * 0.001); self.redrawAll();
    }, {passive: false});
  };

  function el(tag, attrs, text) {
    var e = document.createElement(tag);
    Object.keys(attrs || {}).forEach(function (k) { e.setAttribute(k, attrs[k]); });
    if (text !== undefined) e.textContent = text;
    return e;
  }
  function select(id, label, options) {
    var wrap = el("label", {}, label + " "), s = el("select", {id: id});
    options.forEach(function (o, i) { s.appendChild(el("option", {value: String(i)}, o)); });
    wrap.appendChild(s);
    return wrap;
  }
  function fmtHz(f) { return f.toPrecision(5) + " Hz"; }

  /* The report's section: two linked viewers (full | reduced), modes with MAC pairs, deformations. */
  function report(dataEl) {
    var scene = JSON.parse(dataEl.textContent), body = decodeBody(scene), n = body.n, cache = {};
    function shape(i) { return i < 0 ? null : (cache[i] = cache[i] || decodeShape(scene.shapes[i], n)); }
    var left = new Viewer(document.getElementById("v3d-left"), body);
    var right = new Viewer(document.getElementById("v3d-right"), body, left.cam);
    var labels = Object.keys(scene.bodies), ctl = document.getElementById("v3dctl");
    var legend = document.getElementById("v3dlegend");
    Object.keys(MARK_COLORS).forEach(function (k) {
      if (!body.marks[k]) return;
      var s = el("span"); s.style.background = "rgb(" + MARK_COLORS[k].map(function (v) { return Math.round(v * 255); }).join(",") + ")";
      legend.appendChild(s); var nm = body.marks[k].length;  // nodes, not DOFs
      legend.appendChild(document.createTextNode(k + ": " + nm + (nm === 1 ? " node" : " nodes")));
    });
    ctl.appendChild(select("v3d-view", "show", ["modes", "deformation"]));
    ctl.appendChild(select("v3d-body", "body", labels.length ? labels : ["(none)"]));
    ctl.appendChild(select("v3d-side", "mode of", ["full model", "reduced body"]));
    ctl.appendChild(select("v3d-mode", "mode", []));
    ctl.appendChild(select("v3d-input", "input", scene.deform.inputs));
    ctl.appendChild(select("v3d-freq", "frequency", scene.deform.freqs.map(fmtHz)));
    var sl = el("label", {}, "scale "), slider = el("input", {type: "range", id: "v3d-scale", min: "0", max: "100", value: "40"});
    sl.appendChild(slider); ctl.appendChild(sl);
    var al = el("label", {}, " animate"), anim = el("input", {type: "checkbox", id: "v3d-anim"});
    anim.checked = true; al.insertBefore(anim, al.firstChild); ctl.appendChild(al);
    function $(id) { return document.getElementById(id); }
    function fillModes() {
      var b = scene.bodies[labels[+$("v3d-body").value]], side = +$("v3d-side").value, s = $("v3d-mode"), old = +s.value;
      var list = side === 0 ? scene.full : (b ? b.modes : []);
      s.innerHTML = "";
      list.forEach(function (m, i) { s.appendChild(el("option", {value: String(i)}, (i + 1) + ": " + fmtHz(m.hz))); });
      s.value = String(Math.min(old || 0, Math.max(0, list.length - 1)));
    }
    function update() {
      var view = +$("v3d-view").value, lb = labels[+$("v3d-body").value], b = scene.bodies[lb];
      ["v3d-side", "v3d-mode"].forEach(function (id) { $(id).parentNode.style.display = view === 0 ? "" : "none"; });
      ["v3d-input", "v3d-freq"].forEach(function (id) { $(id).parentNode.style.display = view === 1 ? "" : "none"; });
      var capL = "", capR = "", sl = null, sr = null;
      if (view === 0) {
        var side = +$("v3d-side").value, k = +$("v3d-mode").value;
        if (side === 0 && scene.full[k]) {
          sl = shape(b ? b.full_shapes[k] : scene.full[k].shape);
          capL = "full model: mode " + (k + 1) + ", " + fmtHz(scene.full[k].hz);
          var p = b ? b.pairs[k] : null;
          if (p && p.pair >= 0) {
            sr = shape(b.modes[p.pair].shape);
            capR = lb + ": mode " + (p.pair + 1) + ", " + fmtHz(b.modes[p.pair].hz) + ", MAC " + p.mac.toFixed(4);
          } else capR = lb ? lb + ": no paired mode (MAC " + (p ? p.mac.toFixed(3) : "-") + ")" : "";
        } else if (b && b.modes[k]) {
          var m = b.modes[k];
          sr = shape(m.shape);
          capR = lb + ": mode " + (k + 1) + ", " + fmtHz(m.hz);
          if (m.pair >= 0) {
            sl = shape(b.full_shapes[m.pair]);
            capL = "full model: mode " + (m.pair + 1) + ", " + fmtHz(scene.full[m.pair].hz) + ", MAC " + m.mac.toFixed(4);
          }
        }
      } else {
        var fi = +$("v3d-freq").value, j = +$("v3d-input").value, d = scene.deform;
        if (d.full[fi]) {
          sl = shape(d.full[fi][j]);
          capL = "full model: input " + d.inputs[j] + " at " + fmtHz(d.freqs[fi]);
          var r = d.bodies[lb] ? d.bodies[lb][fi][j] : null;
          if (r) {
            sr = shape(r.shape);
            capR = lb + ": same input and frequency; ‖u − û‖/‖u‖ = " + r.rel_diff.toExponential(2) + " on the shown nodes";
          }
        }
      }
      // one scale for both panels: the full model's amplitude decides, so a wrong amplitude shows
      var sc = +$("v3d-scale").value / 100 * 0.25;
      left.scale = sc;
      right.scale = sc * (sl && sr && view === 1 ? maxNorm(sr) / maxNorm(sl) : 1);
      left.shape = sl; right.shape = sr;
      $("v3d-left-cap").textContent = capL; $("v3d-right-cap").textContent = capR;
      left.redrawAll();
    }
    ["v3d-view", "v3d-body", "v3d-side"].forEach(function (id) { $(id).addEventListener("change", function () { fillModes(); update(); }); });
    ["v3d-mode", "v3d-input", "v3d-freq"].forEach(function (id) { $(id).addEventListener("change", update); });
    slider.addEventListener("input", update);
    var t0 = performance.now(), running = true;
    function tick(t) {
      if (!running) return;
      if (anim.checked) { left.phase = right.phase = ((t - t0) / 1500) * 2 * Math.PI; left.redrawAll(); }
      requestAnimationFrame(tick);
    }
    anim.addEventListener("change", function () { if (!anim.checked) { left.phase = right.phase = 0; left.redrawAll(); } });
    fillModes(); update(); requestAnimationFrame(tick);
    window.flexmorReportView = {left: left, right: right, update: update, stop: function () { running = false; }};
    return window.flexmorReportView;
  }
  return {Viewer: Viewer, decodeBody: decodeBody, decodeShape: decodeShape, report: report, colormap: colormap};
})();

// The report's 3D views: each `.viewer` of the page draws its mesh (WebGL 1, no library), shaded,
// coloured by its normals or, where the page holds a truth, by each vertex's distance to it, with
// the views' cameras as frustums; drag to orbit, wheel to zoom. The data is in the viewer's
// `.mesh-data` (base64 little-endian arrays). With `#selftest` in the address the page draws each
// mesh from two directions (and coloured by error, where it can be) and writes what it drew into
// `#selftest` (the test suite reads it).
"use strict";

(function () {
  const errors = [];
  window.addEventListener("error", (e) => errors.push(String(e.message)));

  function decode(text, Type) {
    const bytes = Uint8Array.from(atob(text), (c) => c.charCodeAt(0));
    return new Type(bytes.buffer);
  }

  function compile(gl, type, source) {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
    return shader;
  }

  function program(gl, vertex, fragment) {
    const p = gl.createProgram();
    gl.attachShader(p, compile(gl, gl.VERTEX_SHADER, vertex));
    gl.attachShader(p, compile(gl, gl.FRAGMENT_SHADER, fragment));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    return p;
  }

  // Column-major 4x4 matrices.
  function perspective(fovy, aspect, near, far) {
    const f = 1 / Math.tan(fovy / 2);
    return [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, (2 * far * near) / (near - far), 0];
  }

  function multiply(a, b) {
    const out = new Array(16).fill(0);
    for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) for (let k = 0; k < 4; k++) out[c * 4 + r] += a[k * 4 + r] * b[c * 4 + k];
    return out;
  }

  function lookAt(eye, target, up) {
    const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    const norm = (a) => { const l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; };
    const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    const z = norm(sub(eye, target));
    const x = norm(cross(up, z));
    const y = cross(z, x);
    return [x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0, -dot(x, eye), -dot(y, eye), -dot(z, eye), 1];
  }

  // The error colour ramp (blue, cyan, yellow, red), as the legend's CSS gradient draws it.
  const RAMP = "vec3 ramp(float t) { t = clamp(t, 0.0, 1.0);" +
    " vec3 a = vec3(0.19, 0.32, 0.87), b = vec3(0.2, 0.8, 0.85), c = vec3(0.95, 0.85, 0.2), d = vec3(0.9, 0.15, 0.12);" +
    " return t < 0.333 ? mix(a, b, t * 3.0) : t < 0.667 ? mix(b, c, t * 3.0 - 1.0) : mix(c, d, t * 3.0 - 2.0); }";
  const MODES = { shaded: 0, normal: 1, error: 2 };

  // One viewer: returns a function that draws it at a turn (yaw) and colour mode, and reads back
  // the share of the canvas that differs from the background.
  function viewer(root) {
    const data = JSON.parse(root.querySelector(".mesh-data").textContent);
    const canvas = root.querySelector("canvas");
    const gl = canvas.getContext("webgl", { preserveDrawingBuffer: true, antialias: true });
    if (!gl) throw new Error("this browser has no WebGL");
    const positions = decode(data.positions, Float32Array);
    const indices = decode(data.indices, Uint32Array);
    const errors = data.errors ? decode(data.errors, Float32Array) : new Float32Array(positions.length / 3);
    if (!gl.getExtension("OES_element_index_uint")) throw new Error("no 32-bit indices in this WebGL");
    // Vertex normals: the area-weighted sum of the faces'.
    const normals = new Float32Array(positions.length);
    for (let f = 0; f < indices.length; f += 3) {
      const [a, b, c] = [indices[f] * 3, indices[f + 1] * 3, indices[f + 2] * 3];
      const u = [positions[b] - positions[a], positions[b + 1] - positions[a + 1], positions[b + 2] - positions[a + 2]];
      const v = [positions[c] - positions[a], positions[c + 1] - positions[a + 1], positions[c + 2] - positions[a + 2]];
      const n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
      for (const i of [a, b, c]) for (let k = 0; k < 3; k++) normals[i + k] += n[k];
    }
    const buffer = (target, array) => { const b = gl.createBuffer(); gl.bindBuffer(target, b); gl.bufferData(target, array, gl.STATIC_DRAW); return b; };
    const positionBuffer = buffer(gl.ARRAY_BUFFER, positions);
    const normalBuffer = buffer(gl.ARRAY_BUFFER, normals);
    const errorBuffer = buffer(gl.ARRAY_BUFFER, errors);
    const indexBuffer = buffer(gl.ELEMENT_ARRAY_BUFFER, indices);
    const surface = program(gl,
      "attribute vec3 p; attribute vec3 n; attribute float e; uniform mat4 m; varying vec3 vn; varying float ve;" +
      "void main() { vn = n; ve = e; gl_Position = m * vec4(p, 1.0); }",
      "precision mediump float; varying vec3 vn; varying float ve; uniform vec3 light; uniform float mode, scale;" + RAMP +
      "void main() { vec3 n = normalize(vn); float d = 0.25 + 0.75 * abs(dot(n, light));" +
      " vec3 colour = mode > 1.5 ? ramp(ve / scale) * (0.55 + 0.45 * d) : mode > 0.5 ? 0.5 + 0.5 * n : vec3(0.82, 0.80, 0.76) * d;" +
      " gl_FragColor = vec4(colour, 1.0); }");
    const lines = program(gl,
      "attribute vec3 p; uniform mat4 m; void main() { gl_Position = m * vec4(p, 1.0); }",
      "precision mediump float; void main() { gl_FragColor = vec4(0.95, 0.55, 0.1, 1.0); }");
    const frustumBuffer = buffer(gl.ARRAY_BUFFER, new Float32Array(data.frustums));
    const centre = data.centre, radius = data.radius;
    const view = { yaw: 0.6, pitch: 0.35, distance: 3.2 * radius, mode: 0 };
    const select = root.querySelector("select.colour");

    function draw() {
      gl.viewport(0, 0, canvas.width, canvas.height);
      gl.clearColor(0.12, 0.13, 0.15, 1);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      gl.enable(gl.DEPTH_TEST);
      const eye = [
        centre[0] + view.distance * Math.cos(view.pitch) * Math.sin(view.yaw),
        centre[1] + view.distance * Math.sin(view.pitch),
        centre[2] + view.distance * Math.cos(view.pitch) * Math.cos(view.yaw),
      ];
      const far = view.distance + 4 * radius + data.frustumReach;
      const m = multiply(perspective(0.8, canvas.width / canvas.height, Math.max(1e-3, view.distance - 2 * radius) / 10, far), lookAt(eye, centre, [0, 1, 0]));
      gl.useProgram(surface);
      gl.uniformMatrix4fv(gl.getUniformLocation(surface, "m"), false, new Float32Array(m));
      const toEye = [eye[0] - centre[0], eye[1] - centre[1], eye[2] - centre[2]];
      const l = Math.hypot(toEye[0], toEye[1], toEye[2]);
      gl.uniform3f(gl.getUniformLocation(surface, "light"), toEye[0] / l, toEye[1] / l, toEye[2] / l);
      gl.uniform1f(gl.getUniformLocation(surface, "mode"), view.mode);
      gl.uniform1f(gl.getUniformLocation(surface, "scale"), data.errorScale || 1);
      for (const [name, b, size] of [["p", positionBuffer, 3], ["n", normalBuffer, 3], ["e", errorBuffer, 1]]) {
        const at = gl.getAttribLocation(surface, name);
        gl.bindBuffer(gl.ARRAY_BUFFER, b);
        gl.enableVertexAttribArray(at);
        gl.vertexAttribPointer(at, size, gl.FLOAT, false, 0, 0);
      }
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, indexBuffer);
      gl.drawElements(gl.TRIANGLES, indices.length, gl.UNSIGNED_INT, 0);
      if (data.frustums.length) {
        gl.useProgram(lines);
        gl.uniformMatrix4fv(gl.getUniformLocation(lines, "m"), false, new Float32Array(m));
        const at = gl.getAttribLocation(lines, "p");
        gl.bindBuffer(gl.ARRAY_BUFFER, frustumBuffer);
        gl.enableVertexAttribArray(at);
        gl.vertexAttribPointer(at, 3, gl.FLOAT, false, 0, 0);
        gl.drawArrays(gl.LINES, 0, data.frustums.length / 3);
      }
    }

    let dragging = null;
    canvas.addEventListener("mousedown", (e) => { dragging = [e.clientX, e.clientY]; });
    window.addEventListener("mouseup", () => { dragging = null; });
    window.addEventListener("mousemove", (e) => {
      if (!dragging) return;
      view.yaw -= (e.clientX - dragging[0]) * 0.01;
      view.pitch = Math.max(-1.5, Math.min(1.5, view.pitch + (e.clientY - dragging[1]) * 0.01));
      dragging = [e.clientX, e.clientY];
      draw();
    });
    canvas.addEventListener("wheel", (e) => {
      e.preventDefault();
      view.distance = Math.max(0.3 * radius, view.distance * Math.exp(e.deltaY * 0.001));
      draw();
    }, { passive: false });
    select.addEventListener("change", () => { view.mode = MODES[select.value]; draw(); });
    // `#colour=normal` or `#colour=error` in the address chooses the colouring.
    const asked = /colour=(\w+)/.exec(location.hash);
    if (asked && select.querySelector("option[value=" + asked[1] + "]")) {
      select.value = asked[1];
      view.mode = MODES[asked[1]];
    }
    draw();

    // Draws at `yaw` in `mode` and returns the share of the canvas that is not background and,
    // of that, the share whose colour is the ramp's warm half (red outweighs blue).
    return function test(yaw, mode) {
      Object.assign(view, { yaw, mode: MODES[mode] });
      draw();
      const pixels = new Uint8Array(canvas.width * canvas.height * 4);
      gl.readPixels(0, 0, canvas.width, canvas.height, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
      let differ = 0, warm = 0;
      for (let i = 0; i < pixels.length; i += 4) {
        if (Math.abs(pixels[i] - 31) + Math.abs(pixels[i + 1] - 33) + Math.abs(pixels[i + 2] - 38) > 24) {
          differ++;
          if (pixels[i] > pixels[i + 2] + 40) warm++;
        }
      }
      return { covered: differ / (canvas.width * canvas.height), warm: warm / Math.max(1, differ) };
    };
  }

  function start() {
    const roots = Array.from(document.querySelectorAll(".viewer"));
    const tests = [];
    for (const root of roots) {
      try {
        tests.push([root, viewer(root)]);
      } catch (e) {
        errors.push(String(e));
        root.querySelector(".mesh-error").textContent = "The 3D view cannot be shown here: " + e;
      }
    }
    if (location.hash === "#selftest") {
      // Each mesh from two directions a quarter turn apart, shaded, and coloured by its error
      // where the page holds one.
      const views = tests.map(([root, test]) => {
        const covered = [0.6, 0.6 + Math.PI / 2].map((yaw) => test(yaw, "shaded").covered);
        const byError = root.querySelector("option[value=error]") ? test(0.6, "error") : null;
        test(0.6, "shaded");
        return { id: root.id, covered, byError };
      });
      document.getElementById("selftest").textContent = JSON.stringify({ views, errors });
    }
  }

  window.addEventListener("load", () => {
    try {
      start();
    } catch (e) {
      errors.push(String(e));
      const out = document.getElementById("selftest");
      if (out) out.textContent = JSON.stringify({ views: [], errors });
    }
  });
})();

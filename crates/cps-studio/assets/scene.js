// cps studio: the robot's and the scene's shapes in WebGL, lit and shaded, under the page's
// 2-D overlay (paths, way points, labels). The shapes are the ones the guard checks (link
// hulls, obstacles), posed by the server's frames; a pair closer than the margin is drawn
// red, a near miss orange. The projection is the overlay's own (app.js's rotate/scale), so
// both layers agree to the pixel. Without WebGL the page draws the skeleton as before.
"use strict";

const Scene3D = (() => {
  const COLORS = {
    body: [0.80, 0.82, 0.86],
    obstacle: [0.78, 0.68, 0.52],
    near: [1.0, 0.58, 0.10],
    collision: [0.86, 0.10, 0.12],
    // An obstacle involved is tinted, so it does not hide the bodies in it.
    obstacleNear: [0.93, 0.70, 0.42],
    obstacleCollision: [0.90, 0.45, 0.40],
    grid: [0.88, 0.88, 0.88],
  };
  let gl = null, program = null, meshes = [], grid = null, loc = {};

  const VERTEX = `
    attribute vec3 position; attribute vec3 normal;
    uniform mat4 model; uniform mat4 view; uniform mat3 turn;
    varying vec3 n;
    void main() {
      n = turn * mat3(model) * normal;
      gl_Position = view * model * vec4(position, 1.0);
    }`;
  const FRAGMENT = `
    precision mediump float;
    uniform vec3 color; uniform float lit;
    varying vec3 n;
    void main() {
      // A light over the viewer's left shoulder: (right, up, depth into the screen).
      vec3 light = normalize(vec3(-0.45, 0.6, -0.65));
      float diffuse = max(dot(normalize(n), light), 0.0);
      float shade = mix(1.0, 0.32 + 0.68 * diffuse, lit);
      gl_FragColor = vec4(color * shade, 1.0);
    }`;

  function shader(kind, text) {
    const s = gl.createShader(kind);
    gl.shaderSource(s, text);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }

  // WebGL on `canvas`; false when the browser has none (the page then draws skeletons).
  function init(canvas) {
    try {
      // No multisampling: flat-shaded hulls need little, and a browser without a GPU
      // (a virtual machine, a headless test) draws in software, where it halves the time.
      gl = canvas.getContext("webgl", { antialias: false });
      if (!gl) return false;
      program = gl.createProgram();
      gl.attachShader(program, shader(gl.VERTEX_SHADER, VERTEX));
      gl.attachShader(program, shader(gl.FRAGMENT_SHADER, FRAGMENT));
      gl.linkProgram(program);
      if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
      for (const a of ["position", "normal"]) loc[a] = gl.getAttribLocation(program, a);
      for (const u of ["model", "view", "turn", "color", "lit"]) loc[u] = gl.getUniformLocation(program, u);
      gl.enable(gl.DEPTH_TEST);
      return true;
    } catch (e) {
      console.warn("no WebGL: the skeleton is drawn instead", e);
      gl = null;
      return false;
    }
  }

  // One buffer of (position, face normal) per corner of every triangle: flat shading.
  function upload(shape) {
    const v = shape.vertices, t = shape.triangles, data = new Float32Array(t.length * 6);
    for (let k = 0; k < t.length; k += 3) {
      const p = [0, 1, 2].map(j => [v[3 * t[k + j]], v[3 * t[k + j] + 1], v[3 * t[k + j] + 2]]);
      const a = p[1].map((x, i) => x - p[0][i]), b = p[2].map((x, i) => x - p[0][i]);
      const n = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
      const len = Math.hypot(...n) || 1;
      for (let j = 0; j < 3; j++) data.set([...p[j], ...n.map(x => x / len)], (k + j) * 6);
    }
    const buffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    return { buffer, count: t.length, name: shape.name, frame: shape.frame };
  }

  // The robot's and the scene's shapes (RobotView.shapes), uploaded once.
  function setShapes(shapes) {
    if (!gl) return;
    meshes = [
      ...shapes.bodies.map(b => ({ ...upload(b), obstacle: false })),
      ...shapes.obstacles.map(o => ({ ...upload(o), obstacle: true })),
    ];
  }

  // A floor grid of 10 cm squares at height `floor` about `center` (x, y).
  function setGrid(center, floor) {
    const data = [];
    for (let i = -10; i <= 10; i++) {
      const a = center[0] + i * 0.1, b = center[1] + i * 0.1;
      data.push(a, center[1] - 1, floor, 0, 0, 1, a, center[1] + 1, floor, 0, 0, 1);
      data.push(center[0] - 1, b, floor, 0, 0, 1, center[0] + 1, b, floor, 0, 0, 1);
    }
    grid = grid || { buffer: gl.createBuffer() };
    grid.count = data.length / 6;
    gl.bindBuffer(gl.ARRAY_BUFFER, grid.buffer);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(data), gl.STATIC_DRAW);
  }

  function attributes(buffer) {
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.enableVertexAttribArray(loc.position);
    gl.vertexAttribPointer(loc.position, 3, gl.FLOAT, false, 24, 0);
    gl.enableVertexAttribArray(loc.normal);
    gl.vertexAttribPointer(loc.normal, 3, gl.FLOAT, false, 24, 12);
  }

  // A 3 × 4 pose (rows) as a column-major 4 × 4 matrix.
  function matrix(p) {
    return new Float32Array([p[0], p[4], p[8], 0, p[1], p[5], p[9], 0, p[2], p[6], p[10], 0, p[3], p[7], p[11], 1]);
  }
  const IDENTITY = matrix([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]);

  // The view's turn: world → (screen right, screen up, depth into the screen), by rows.
  function turn(view) {
    const cy = Math.cos(view.yaw), sy = Math.sin(view.yaw), cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
    return [[cy, -sy, 0], [sp * sy, sp * cy, cp], [cp * sy, cp * cy, -sp]];
  }

  // The overlay's orthographic projection as a clip-space matrix: the turn, scaled to the
  // canvas, depth ±5 m.
  function viewMatrix(view, width, height, scale) {
    const rows = turn(view);
    const k = [2 * scale / width, 2 * scale / height, 0.2];
    const m = new Float32Array(16);
    for (let r = 0; r < 3; r++) {
      let t = 0;
      for (let c = 0; c < 3; c++) {
        m[4 * c + r] = k[r] * rows[r][c];
        t -= rows[r][c] * view.center[c];
      }
      m[12 + r] = k[r] * t;
    }
    m[15] = 1;
    return m;
  }

  // Draws the shapes at `pose` (frames, RobotView.pose) with `near` (NearView list)
  // coloured; returns the names coloured, `name:red` or `name:orange`.
  function draw(view, scale, pose, near, margin) {
    if (!gl) return [];
    const c = gl.canvas;
    gl.viewport(0, 0, c.width, c.height);
    gl.clearColor(1, 1, 1, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.useProgram(program);
    gl.uniformMatrix4fv(loc.view, false, viewMatrix(view, c.width, c.height, scale));
    const rows = turn(view);
    gl.uniformMatrix3fv(loc.turn, false, new Float32Array([0, 1, 2].flatMap(col => rows.map(r => r[col]))));
    if (grid) {
      attributes(grid.buffer);
      gl.uniformMatrix4fv(loc.model, false, IDENTITY);
      gl.uniform3fv(loc.color, COLORS.grid);
      gl.uniform1f(loc.lit, 0);
      gl.drawArrays(gl.LINES, 0, grid.count);
    }
    // The worst of each shape's pairs: red within the margin, orange nearer than `near`.
    const bodies = meshes.filter(m => !m.obstacle).length, worst = new Map();
    const mark = (i, d) => worst.set(i, Math.min(worst.has(i) ? worst.get(i) : Infinity, d));
    for (const n of near || []) {
      mark(n.body, n.distance);
      mark(n.other_body !== null ? n.other_body : bodies + n.obstacle, n.distance);
    }
    gl.uniform1f(loc.lit, 1);
    const named = [];
    meshes.forEach((m, i) => {
      if (!m.obstacle && !(pose && pose[m.frame])) return;
      let color = m.obstacle ? COLORS.obstacle : COLORS.body;
      if (worst.has(i)) {
        const red = worst.get(i) < margin;
        color = m.obstacle ? (red ? COLORS.obstacleCollision : COLORS.obstacleNear)
          : red ? COLORS.collision : COLORS.near;
        named.push(`${m.name}:${red ? "red" : "orange"}`);
      }
      attributes(m.buffer);
      gl.uniformMatrix4fv(loc.model, false, m.obstacle ? IDENTITY : matrix(pose[m.frame]));
      gl.uniform3fv(loc.color, color);
      gl.drawArrays(gl.TRIANGLES, 0, m.count);
    });
    return [...new Set(named)];
  }

  // What was drawn, for tests: distinct shades among the non-white pixels, how many pixels
  // have the collision's hue (red, or an obstacle's red tint), and a checksum of them all.
  function census() {
    if (!gl) return null;
    const c = gl.canvas, px = new Uint8Array(c.width * c.height * 4);
    gl.readPixels(0, 0, c.width, c.height, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const shades = new Set();
    let red = 0, drawn = 0, sum = 0;
    for (let i = 0; i < px.length; i += 4) {
      const r = px[i], g = px[i + 1], b = px[i + 2];
      if (r > 250 && g > 250 && b > 250) continue;
      drawn += 1;
      shades.add((r << 16) | (g << 8) | b);
      sum = (sum * 31 + i + r + 7 * g + 13 * b) % 1000000007;
      if (r > 60 && r > 1.6 * g && r > 1.6 * b) red += 1;
    }
    return { shades: shades.size, red, drawn, sum };
  }

  // Waits until the drawing is done (one pixel read back).
  function finish() {
    if (gl) gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
  }

  return { init, setShapes, setGrid, draw, census, finish, get active() { return gl !== null && meshes.length > 0; } };
})();

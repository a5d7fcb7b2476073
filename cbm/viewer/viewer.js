// Interactive plan viewer: a canvas, an orbit camera (drag to turn, wheel to
// zoom) and a slider / play button over the stances and the motions between
// them. The robot is drawn from its own visual meshes, shaded, together with
// the soft bodies (coloured by displacement) and the prints, far triangles
// first. No library, no network.
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("plan-data").textContent);
  var canvas = document.getElementById("view");
  var context = canvas.getContext("2d");
  var slider = document.getElementById("slider");
  var label = document.getElementById("label");
  var playButton = document.getElementById("play");
  var showRobot = document.getElementById("show-robot");
  var showGrid = document.getElementById("show-grid");
  var showFrames = document.getElementById("show-frames");
  var lo = data.bounds[0], hi = data.bounds[1];
  var target = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2];
  var radius = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  // One camera for the whole plan: it never moves between stances.
  var camera = { azimuth: data.camera_azimuth, elevation: 0.35, distance: 2.2 * radius };
  var index = 0, playing = null;
  var ROBOT_RGB = data.robot_colour;
  var FORCE = "#9467bd";
  // "#hide=robot" in the address hides the robot (as its checkbox does); "#frames" shows the frames.
  if (window.location.hash.indexOf("hide=robot") >= 0) { showRobot.checked = false; }
  if (window.location.hash.indexOf("frames") >= 0) { showFrames.checked = true; }

  // Timeline: each stance, then the interior samples of the motion that leaves it.
  var timeline = [];
  data.stances.forEach(function (stance, i) {
    timeline.push({ stance: i, robot: stance.robot, segments: stance.segments, text: stance.label });
    (data.motions || []).forEach(function (motion) {
      if (motion.from !== i) { return; }
      motion.robot.forEach(function (pose, k) {
        timeline.push({
          stance: i, robot: pose, segments: null, forces: false,
          text: "motion " + i + " \u2192 " + (i + 1) + " (" + motion.moving + "), sample " + (k + 1) + "/" +
            motion.robot.length + ", t = " + motion.times[k].toFixed(2) + " s"
        });
      });
    });
  });

  var colours = {};
  data.stances.forEach(function (stance) {
    stance.polygons.forEach(function (print) { colours[print.robot_surface] = print.colour; });
  });

  function viridis(t) {
    // Piecewise-linear approximation of matplotlib's viridis, t in [0, 1].
    var stops = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
    t = Math.min(1, Math.max(0, t)) * (stops.length - 1);
    var i = Math.min(stops.length - 2, Math.floor(t)), f = t - i, a = stops[i], b = stops[i + 1];
    return [0, 1, 2].map(function (k) { return a[k] + f * (b[k] - a[k]); });
  }

  function rgb(c, light) {
    return "rgb(" + c.map(function (v) { return Math.round(Math.min(255, v * light)); }).join(",") + ")";
  }

  function hexRgb(hex) {
    return [1, 3, 5].map(function (i) { return parseInt(hex.substr(i, 2), 16); });
  }

  function basis() {
    var ca = Math.cos(camera.azimuth), sa = Math.sin(camera.azimuth);
    var ce = Math.cos(camera.elevation), se = Math.sin(camera.elevation);
    return { back: [ce * ca, ce * sa, se], right: [-sa, ca, 0], up: [-se * ca, -se * sa, ce] };
  }

  function projector() {
    var b = basis(), f = 1.2 * Math.min(canvas.width, canvas.height);
    var project = function (p) {
      var d = [p[0] - target[0], p[1] - target[1], p[2] - target[2]];
      var x = d[0] * b.right[0] + d[1] * b.right[1] + d[2] * b.right[2];
      var y = d[0] * b.up[0] + d[1] * b.up[1] + d[2] * b.up[2];
      var z = Math.max(camera.distance - (d[0] * b.back[0] + d[1] * b.back[1] + d[2] * b.back[2]), 1e-3);
      return [canvas.width / 2 + f * x / z, canvas.height / 2 - f * y / z, z];
    };
    project.back = b.back;
    return project;
  }

  function line(project, a, b, colour, width) {
    var p = project(a), q = project(b);
    context.strokeStyle = colour;
    context.lineWidth = width;
    context.beginPath();
    context.moveTo(p[0], p[1]);
    context.lineTo(q[0], q[1]);
    context.stroke();
  }

  function shade(project, points) {
    // Lambert light from the camera, both sides lit (URDF meshes are not all closed).
    var u = [0, 1, 2].map(function (k) { return points[1][k] - points[0][k]; });
    var v = [0, 1, 2].map(function (k) { return points[2][k] - points[0][k]; });
    var n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    var length = Math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) || 1;
    var b = project.back;
    return 0.45 + 0.55 * Math.abs((n[0] * b[0] + n[1] * b[1] + n[2] * b[2]) / length);
  }

  function robotFaces(project, poses, faces) {
    data.robot.meshes.forEach(function (mesh, m) {
      var T = poses[m];
      var world = mesh.vertices.map(function (p) {
        return [
          T[0] * p[0] + T[1] * p[1] + T[2] * p[2] + T[3],
          T[4] * p[0] + T[5] * p[1] + T[6] * p[2] + T[7],
          T[8] * p[0] + T[9] * p[1] + T[10] * p[2] + T[11]
        ];
      });
      var screen = world.map(project);
      mesh.triangles.forEach(function (t) {
        var points = [world[t[0]], world[t[1]], world[t[2]]];
        faces.push({
          screen: [screen[t[0]], screen[t[1]], screen[t[2]]],
          depth: (screen[t[0]][2] + screen[t[1]][2] + screen[t[2]][2]) / 3,
          fill: rgb(ROBOT_RGB, shade(project, points)), stroke: null
        });
      });
    });
  }

  function grid(project) {
    var step = data.grid_spacing, z = data.grid_height;
    var x0 = Math.floor(lo[0] / step) * step, x1 = Math.ceil(hi[0] / step) * step;
    var y0 = Math.floor(lo[1] / step) * step, y1 = Math.ceil(hi[1] / step) * step;
    for (var x = x0; x <= x1 + 1e-9; x += step) { line(project, [x, y0, z], [x, y1, z], "#ddd", 1); }
    for (var y = y0; y <= y1 + 1e-9; y += step) { line(project, [x0, y, z], [x1, y, z], "#ddd", 1); }
    // World axes at the origin, 0.2 m: x red, y green, z blue.
    line(project, [0, 0, z], [0.2, 0, z], "#d62728", 2);
    line(project, [0, 0, z], [0, 0.2, z], "#2ca02c", 2);
    line(project, [0, 0, z], [0, 0, z + 0.2], "#1f77b4", 2);
  }

  function frames(project, stance) {
    // Each frame's axes, 0.15 m: x red, y green, z blue, and its name.
    (stance.frames || []).forEach(function (frame) {
      var T = frame.transform, origin = [T[3], T[7], T[11]];
      ["#d62728", "#2ca02c", "#1f77b4"].forEach(function (colour, k) {
        line(project, origin, [origin[0] + 0.15 * T[k], origin[1] + 0.15 * T[4 + k], origin[2] + 0.15 * T[8 + k]], colour, 3);
      });
      var p = project(origin);
      context.fillStyle = "#333";
      context.font = "11px sans-serif";
      context.fillText(frame.name, p[0] + 4, p[1] + 12);
    });
  }

  function labelAt(text, x, y, placed) {
    // Moved down, a line at a time, off the labels already drawn: two soles' equal
    // forces put their labels on one spot.
    var width = context.measureText(text).width, height = 14;
    var clash = function (box) { return x < box[0] + box[2] && box[0] < x + width && y - height < box[1] && box[1] - height < y; };
    for (var tries = 0; tries < 20 && placed.some(clash); tries++) { y += height; }
    placed.push([x, y, width]);
    context.fillText(text, x, y);
  }

  function arrow(project, f, placed) {
    var magnitude = Math.sqrt(f.force[0] * f.force[0] + f.force[1] * f.force[1] + f.force[2] * f.force[2]);
    if (magnitude < 1e-9) { return; }
    // Linear in the force, but never shorter than 6 cm, and labelled: a palm's 20 N stays legible.
    var length = Math.max(data.force_scale * magnitude, 0.06);
    var tip = [0, 1, 2].map(function (k) { return f.point[k] + length * f.force[k] / magnitude; });
    line(project, f.point, tip, FORCE, 2.5);
    var p = project(f.point), q = project(tip);
    var angle = Math.atan2(q[1] - p[1], q[0] - p[0]);
    context.fillStyle = FORCE;
    context.beginPath();
    context.moveTo(q[0], q[1]);
    context.lineTo(q[0] - 10 * Math.cos(angle - 0.4), q[1] - 10 * Math.sin(angle - 0.4));
    context.lineTo(q[0] - 10 * Math.cos(angle + 0.4), q[1] - 10 * Math.sin(angle + 0.4));
    context.closePath();
    context.fill();
    context.font = "bold 13px sans-serif";
    labelAt(magnitude.toFixed(0) + " N", q[0] + 6, q[1] - 4, placed);
  }

  function draw() {
    var frame = timeline[index];
    var stance = data.stances[frame.stance];
    var project = projector();
    context.clearRect(0, 0, canvas.width, canvas.height);
    if (showGrid.checked) { grid(project); }
    data.boxes.forEach(function (box) {
      box.edges.forEach(function (e) { line(project, e[0], e[1], "#999", 1); });
    });
    // Every face of the scene in one list, far first (painter's algorithm).
    var faces = [];
    var top = Math.max(data.max_displacement, 1e-9);
    stance.deformables.forEach(function (body) {
      var screen = body.vertices.map(project);
      body.triangles.forEach(function (t) {
        var value = (body.magnitude[t[0]] + body.magnitude[t[1]] + body.magnitude[t[2]]) / 3;
        var points = [body.vertices[t[0]], body.vertices[t[1]], body.vertices[t[2]]];
        var c = rgb(viridis(value / top), shade(project, points));
        faces.push({
          screen: [screen[t[0]], screen[t[1]], screen[t[2]]],
          depth: (screen[t[0]][2] + screen[t[1]][2] + screen[t[2]][2]) / 3, fill: c, stroke: c
        });
      });
    });
    stance.polygons.forEach(function (print) {
      var screen = print.points.map(project);
      // A print lies on its support: drawn just in front of it.
      var depth = screen.reduce(function (s, p) { return s + p[2]; }, 0) / screen.length - 0.01;
      faces.push({ screen: screen, depth: depth, fill: print.colour || "#2ca02c", stroke: "#000" });
    });
    if (showRobot.checked && data.robot.meshes.length) { robotFaces(project, frame.robot, faces); }
    faces.sort(function (a, b) { return b.depth - a.depth; });
    faces.forEach(function (face) {
      context.beginPath();
      face.screen.forEach(function (p, i) { if (i === 0) { context.moveTo(p[0], p[1]); } else { context.lineTo(p[0], p[1]); } });
      context.closePath();
      context.fillStyle = face.fill;
      context.fill();
      if (face.stroke) { context.strokeStyle = face.stroke; context.lineWidth = 0.5; context.stroke(); }
    });
    if (showRobot.checked && !data.robot.meshes.length && frame.segments) {
      frame.segments.forEach(function (s) { line(project, s[0], s[1], "#111", 2.5); });
    }
    if (showFrames.checked && frame.segments) { frames(project, stance); }
    var placed = [];
    if (frame.forces !== false) { stance.forces.forEach(function (f) { arrow(project, f, placed); }); }
    label.textContent = frame.text;
    slider.value = String(index);
    // "ok" once drawn, unless an error came first: it stays what the page says.
    if (document.body.dataset.status.indexOf("error") !== 0) { document.body.dataset.status = "ok"; }
  }

  function legend() {
    var parts = Object.keys(colours).map(function (name) {
      return '<span class="swatch" style="background:' + colours[name] + '"></span>' + name;
    });
    parts.push('<span class="swatch" style="background:' + FORCE + '"></span>contact force (' +
      (data.force_legend * data.force_scale).toFixed(2) + " m = " + data.force_legend + " N, at least 6 cm)");
    parts.push('<span class="swatch" style="background:' + rgb(viridis(0), 1) + '"></span>0 mm' +
      '<span class="swatch" style="background:' + rgb(viridis(1), 1) + '"></span>' +
      (1000 * data.max_displacement).toFixed(1) + " mm displacement");
    parts.push("grid " + data.grid_spacing + " m, axes x red, y green, z blue");
    document.getElementById("legend").innerHTML = data.title + ": " + parts.join(" ");
  }

  function resize() {
    var bars = document.getElementById("bar").offsetHeight + document.getElementById("legend").offsetHeight;
    canvas.width = Math.max(320, window.innerWidth);
    canvas.height = Math.max(240, window.innerHeight - bars - 4);
  }

  var dragging = null;
  canvas.addEventListener("mousedown", function (event) { dragging = [event.clientX, event.clientY]; });
  window.addEventListener("mouseup", function () { dragging = null; });
  window.addEventListener("mousemove", function (event) {
    if (!dragging) { return; }
    camera.azimuth -= 0.01 * (event.clientX - dragging[0]);
    camera.elevation = Math.max(-1.5, Math.min(1.5, camera.elevation + 0.01 * (event.clientY - dragging[1])));
    dragging = [event.clientX, event.clientY];
    draw();
  });
  canvas.addEventListener("wheel", function (event) {
    event.preventDefault();
    camera.distance *= event.deltaY > 0 ? 1.1 : 1 / 1.1;
    draw();
  });
  window.addEventListener("resize", function () { resize(); if (timeline.length) { draw(); } });
  showRobot.addEventListener("change", draw);
  showGrid.addEventListener("change", draw);
  showFrames.addEventListener("change", draw);
  slider.max = String(Math.max(timeline.length - 1, 0));
  slider.addEventListener("input", function () { index = Number(slider.value); draw(); });
  playButton.addEventListener("click", function () {
    if (playing !== null) { clearInterval(playing); playing = null; playButton.textContent = "Play"; return; }
    playButton.textContent = "Pause";
    playing = setInterval(function () {
      index = (index + 1) % timeline.length;
      draw();
    }, 250);
  });
  legend();
  resize();
  if (timeline.length === 0) { label.textContent = "empty plan"; document.body.dataset.status = "ok"; return; }
  draw();
})();

// Facetscan 3D view: the scan's points, the recognized models in their poses (translucent solids with
// labels), the table plane; orbit / zoom / pan (OrbitControls); click an object to select it.
// A classic script (no modules, no build step) so that a report opens from disk: needs three.min.js and
// OrbitControls.js (Debian libjs-three) loaded before it. Defines window.FacetView.
(function () {
  'use strict';
  const T = window.THREE;
  const FacetView = {};
  const BACKGROUND = 0x1d232b;
  FacetView.BACKGROUND = BACKGROUND;

  // The points format of /api/scans/ID/points (docs/web-api.md).
  FacetView.decodePoints = function (buf) {
    const dv = new DataView(buf);
    const magic = String.fromCharCode(dv.getUint8(0), dv.getUint8(1), dv.getUint8(2), dv.getUint8(3));
    if (magic !== 'FSPT' || dv.getUint32(4, true) !== 1) throw new Error('not a Facetscan points blob');
    const n = dv.getUint32(8, true), flags = dv.getUint32(12, true);
    const min = [0, 1, 2].map((k) => dv.getFloat32(16 + 4 * k, true));
    const max = [0, 1, 2].map((k) => dv.getFloat32(28 + 4 * k, true));
    let off = 40;
    const pos = new Float32Array(buf, off, 3 * n);
    off += 12 * n;
    const obj = new Uint8Array(buf, off, n);
    off += n;
    if (off % 2) off += 1;
    const region = flags & 1 ? new Uint16Array(buf, off, n) : null;
    return { n, pos, obj, region, min, max };
  };

  FacetView.base64ToBuffer = function (b64) {
    const s = atob(b64);
    const u = new Uint8Array(s.length);
    for (let i = 0; i < s.length; ++i) u[i] = s.charCodeAt(i);
    return u.buffer;
  };

  // Turbo-like colour map, t in [0, 1].
  function heat(t, out) {
    t = Math.min(1, Math.max(0, t));
    const r = 0.13572 + t * (4.6153 + t * (-42.66 + t * (132.13 + t * (-152.94 + t * 59.29))));
    const g = 0.0914 + t * (2.1942 + t * (4.8430 + t * (-14.185 + t * (4.2773 + t * 2.8296))));
    const b = 0.1067 + t * (12.641 + t * (-60.582 + t * (110.36 + t * (-89.903 + t * 27.348))));
    out[0] = Math.min(1, Math.max(0, r));
    out[1] = Math.min(1, Math.max(0, g));
    out[2] = Math.min(1, Math.max(0, b));
  }
  function hashColour(k, out) {
    const h = ((k * 2654435761) >>> 0) / 4294967296;
    const c = new T.Color().setHSL(h, 0.65, 0.55);
    out[0] = c.r;
    out[1] = c.g;
    out[2] = c.b;
  }
  function hexColour(s) {
    return new T.Color(s);
  }

  function fmt(x, d) {
    return Number(x).toFixed(d === undefined ? 1 : d);
  }
  function esc(s) {
    return String(s).replace(/[&<>"']/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' })[c]);
  }
  FacetView.escape = esc;

  // Axis-angle of a row-major 3x3 rotation.
  FacetView.axisAngle = function (R) {
    const tr = R[0][0] + R[1][1] + R[2][2];
    const angle = Math.acos(Math.min(1, Math.max(-1, (tr - 1) / 2)));
    let ax = [R[2][1] - R[1][2], R[0][2] - R[2][0], R[1][0] - R[0][1]];
    let len = Math.hypot(ax[0], ax[1], ax[2]);
    if (angle * 180 / Math.PI < 0.05) return { deg: 0, axis: [0, 0, 1] };
    if (len < 1e-6) {  // 180 degrees: the axis from the diagonal
      ax = [Math.sqrt(Math.max(0, (R[0][0] + 1) / 2)), Math.sqrt(Math.max(0, (R[1][1] + 1) / 2)),
        Math.sqrt(Math.max(0, (R[2][2] + 1) / 2))];
      if (R[0][1] < 0) ax[1] = -ax[1];
      if (R[0][2] < 0) ax[2] = -ax[2];
      len = Math.hypot(ax[0], ax[1], ax[2]);
    }
    return { deg: angle * 180 / Math.PI, axis: ax.map((v) => v / len) };
  };

  FacetView.objectName = function (o) {
    return o.model + (o.instance > 0 ? ' #' + (o.instance + 1) : '');
  };

  // The details of one object (model, pose, confidence, faces, alternatives, ambiguity) as HTML.
  FacetView.objectDetailsHTML = function (o, scene) {
    const aa = FacetView.axisAngle(o.rotation);
    const model = scene && scene.models ? scene.models[o.model] : null;
    const rows = [];
    rows.push(['model', esc(FacetView.objectName(o))]);
    rows.push(['position (mm)', '(' + o.translation.map((v) => fmt(v)).join(', ') + ')']);
    rows.push(['rotation', fmt(aa.deg) + '° about (' + aa.axis.map((v) => fmt(v, 2)).join(', ') + ')']);
    rows.push(['rotation matrix', '<span class="mono">' + o.rotation.map((r) => '[' + r.map((v) => fmt(v, 3)).join(' ') + ']').join('<br>') + '</span>']);
    rows.push(['confidence', fmt(o.confidence, 2) + (o.ambiguous ? ' (ambiguous; fit ' + fmt(o.fit, 2) + ')' : '')]);
    rows.push(['faces matched / visible', o.faces_matched + ' / ' + o.faces_visible +
      (o.faces_matched_by_search !== undefined ? ' (' + o.faces_matched_by_search + ' by the search)' : '')]);
    rows.push(['cost', fmt(o.cost, 4)]);
    if (o.verification) rows.push(['fit', o.verification.inliers + ' inlier points, RMS ' + fmt(o.verification.rms_mm, 2) + ' mm']);
    const alts = o.alternatives || [];
    rows.push(['alternatives', alts.length ? alts.map((a) => esc(a.model) + ' (' + fmt(a.confidence, 2) +
      (a.fit !== undefined ? ', fit ' + fmt(a.fit, 2) : '') + ')').join(', ') : 'none']);
    const amb = [];
    if (alts.length) amb.push('the view fits ' + alts.map((a) => esc(a.model)).join(', ') + ' as well (their differences are out of view)');
    if (o.translation_underdetermined) amb.push('position free along (' + o.translation_underdetermined.direction.map((v) => fmt(v, 2)).join(', ') + ')');
    if (model && model.symmetry_order > 1) amb.push('rotation up to the model\'s ' + model.symmetry_order + ' symmetries');
    rows.push(['ambiguity', amb.length ? amb.join('; ') : 'none: unique']);
    return '<table class="kv">' + rows.map((r) => '<tr><th>' + r[0] + '</th><td>' + r[1] + '</td></tr>').join('') + '</table>';
  };

  function faceGeometry(face) {
    const n = new T.Vector3().fromArray(face.normal).normalize();
    const u = Math.abs(n.x) < 0.9 ? new T.Vector3(1, 0, 0) : new T.Vector3(0, 1, 0);
    u.sub(n.clone().multiplyScalar(u.dot(n))).normalize();
    const v = new T.Vector3().crossVectors(n, u);
    const loops3 = face.loops.map((l) => l.map((p) => new T.Vector3().fromArray(p)));
    const loops2 = loops3.map((l) => l.map((p) => new T.Vector2(p.dot(u), p.dot(v))));
    const tris = T.ShapeUtils.triangulateShape(loops2[0], loops2.slice(1));
    const verts = [].concat(...loops3);
    const pos = new Float32Array(verts.length * 3);
    verts.forEach((p, i) => p.toArray(pos, 3 * i));
    const g = new T.BufferGeometry();
    g.setAttribute('position', new T.BufferAttribute(pos, 3));
    g.setIndex([].concat(...tris));
    g.computeVertexNormals();
    return g;
  }

  function edgeGeometry(faces) {
    const pts = [];
    for (const f of faces)
      for (const l of f.loops)
        for (let i = 0; i < l.length; ++i) pts.push(...l[i], ...l[(i + 1) % l.length]);
    const g = new T.BufferGeometry();
    g.setAttribute('position', new T.BufferAttribute(new Float32Array(pts), 3));
    return g;
  }

  function labelSprite(text, colour, height) {
    const c = document.createElement('canvas');
    const ctx = c.getContext('2d');
    const font = 'bold 44px sans-serif';
    ctx.font = font;
    const w = Math.ceil(ctx.measureText(text).width) + 28;
    c.width = w;
    c.height = 64;
    ctx.font = font;
    ctx.fillStyle = 'rgba(15,18,22,0.78)';
    ctx.fillRect(0, 0, w, 64);
    ctx.fillStyle = colour;
    ctx.fillRect(0, 0, 10, 64);
    ctx.fillStyle = '#ffffff';
    ctx.textBaseline = 'middle';
    ctx.fillText(text, 18, 34);
    const tex = new T.CanvasTexture(c);
    tex.minFilter = T.LinearFilter;
    const s = new T.Sprite(new T.SpriteMaterial({ map: tex, depthTest: false, transparent: true }));
    s.scale.set(height * w / 64, height, 1);
    s.renderOrder = 10;
    return s;
  }

  FacetView.create = function (container, opts) {
    opts = opts || {};
    const renderer = new T.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    renderer.setClearColor(BACKGROUND, 1);
    container.appendChild(renderer.domElement);
    const scene = new T.Scene();
    const camera = new T.PerspectiveCamera(40, 1, 1, 20000);
    camera.up.set(0, 0, 1);
    camera.position.set(0, -600, 600);
    const controls = new T.OrbitControls(camera, renderer.domElement);
    controls.screenSpacePanning = true;
    scene.add(new T.AmbientLight(0xffffff, 0.55));
    const sun = new T.DirectionalLight(0xffffff, 0.7);
    sun.position.set(0.4, -0.6, 1);
    scene.add(sun);
    const root = new T.Group();
    scene.add(root);

    const state = { data: null, pts: null, mode: opts.mode || 'height', selected: -1, objects: [], pointsObj: null, radius: 300 };
    const listeners = [];
    let pending = false;
    function render() {
      pending = false;
      renderer.render(scene, camera);
    }
    function requestRender() {
      if (!pending) {
        pending = true;
        requestAnimationFrame(render);
      }
    }
    function resize() {
      const w = container.clientWidth || 640, h = container.clientHeight || 480;
      renderer.setSize(w, h, true);
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
      render();
    }
    controls.addEventListener('change', requestRender);
    window.addEventListener('resize', resize);

    function clear() {
      while (root.children.length) {
        const c = root.children.pop();
        c.traverse((o) => {
          if (o.geometry) o.geometry.dispose();
          if (o.material) {
            if (o.material.map) o.material.map.dispose();
            o.material.dispose();
          }
        });
      }
      state.objects = [];
      state.pointsObj = null;
    }

    function colourPoints() {
      const p = state.pts, d = state.data;
      if (!p || !state.pointsObj) return;
      const col = state.pointsObj.geometry.getAttribute('color');
      const a = col.array, tmp = [0, 0, 0];
      const zmin = p.min[2], zr = Math.max(1e-6, p.max[2] - p.min[2]);
      const objCols = (d.objects || []).map((o) => hexColour(o.colour));
      for (let i = 0; i < p.n; ++i) {
        const z = (p.pos[3 * i + 2] - zmin) / zr;
        if (state.mode === 'segment' && p.region) {
          const r = p.region[i];
          if (r === 0xffff) tmp[0] = tmp[1] = tmp[2] = 0.35;
          else hashColour(r + 1, tmp);
        } else if (state.mode === 'object') {
          const o = p.obj[i];
          if (o !== 255 && objCols[o]) {
            tmp[0] = objCols[o].r;
            tmp[1] = objCols[o].g;
            tmp[2] = objCols[o].b;
          } else tmp[0] = tmp[1] = tmp[2] = 0.3 + 0.5 * z;
        } else heat(z, tmp);
        a[3 * i] = tmp[0];
        a[3 * i + 1] = tmp[1];
        a[3 * i + 2] = tmp[2];
      }
      col.needsUpdate = true;
    }

    function highlight() {
      state.objects.forEach((g, i) => {
        const on = i === state.selected;
        g.userData.faces.forEach((m) => {
          m.material.opacity = on ? 0.62 : 0.32;
          m.material.emissive.setHex(on ? 0x333333 : 0x000000);
        });
        g.userData.edges.material.color.set(on ? '#ffffff' : g.userData.colour);
      });
      requestRender();
    }

    const viewer = {
      renderer, camera, controls, scene,
      // data: the /api/scans/ID JSON; points: the decoded points (decodePoints) or null.
      setScan(data, points) {
        clear();
        state.data = data;
        state.pts = points;
        state.selected = -1;
        const b = data.bounds || { min: [-200, -200, 0], max: [200, 200, 100] };
        const c = new T.Vector3((b.min[0] + b.max[0]) / 2, (b.min[1] + b.max[1]) / 2, (b.min[2] + b.max[2]) / 2);
        const radius = Math.max(50, 0.5 * Math.hypot(b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]));
        state.radius = radius;
        if (points && points.n > 0) {
          const g = new T.BufferGeometry();
          g.setAttribute('position', new T.BufferAttribute(points.pos, 3));
          g.setAttribute('color', new T.BufferAttribute(new Float32Array(3 * points.n), 3));
          const area = Math.max(1, (points.max[0] - points.min[0]) * (points.max[1] - points.min[1]));
          const size = Math.max(0.5, 1.6 * Math.sqrt(area / points.n));
          state.pointsObj = new T.Points(g, new T.PointsMaterial({ size, vertexColors: true, sizeAttenuation: true }));
          root.add(state.pointsObj);
          colourPoints();
        }
        if (data.table) {
          const n = new T.Vector3().fromArray(data.table.normal).normalize();
          const onPlane = c.clone().sub(n.clone().multiplyScalar(n.dot(c) - data.table.d));
          const w = Math.max(100, (b.max[0] - b.min[0]) * 1.15), h = Math.max(100, (b.max[1] - b.min[1]) * 1.15);
          const plane = new T.Mesh(new T.PlaneGeometry(w, h),
            new T.MeshBasicMaterial({ color: 0x6f8fb0, transparent: true, opacity: 0.16, side: T.DoubleSide, depthWrite: false }));
          plane.quaternion.setFromUnitVectors(new T.Vector3(0, 0, 1), n);
          plane.position.copy(onPlane.clone().sub(n.clone().multiplyScalar(0.3)));
          plane.name = 'table';
          root.add(plane);
          const grid = new T.GridHelper(Math.max(w, h), Math.round(Math.max(w, h) / 50), 0x52677d, 0x34414f);
          grid.quaternion.setFromUnitVectors(new T.Vector3(0, 1, 0), n);
          grid.position.copy(onPlane.clone().sub(n.clone().multiplyScalar(0.5)));
          root.add(grid);
        }
        (data.objects || []).forEach((o, i) => {
          const m = data.models && data.models[o.model];
          const g = new T.Group();
          g.matrixAutoUpdate = false;
          const R = o.rotation, t = o.translation;
          g.matrix.set(R[0][0], R[0][1], R[0][2], t[0], R[1][0], R[1][1], R[1][2], t[1], R[2][0], R[2][1], R[2][2], t[2], 0, 0, 0, 1);
          g.userData = { index: i, faces: [], colour: o.colour };
          if (m) {
            for (const f of m.faces) {
              const mesh = new T.Mesh(faceGeometry(f), new T.MeshLambertMaterial({
                color: o.colour, transparent: true, opacity: 0.32, side: T.DoubleSide, depthWrite: false, emissive: 0x000000 }));
              mesh.userData.index = i;
              g.userData.faces.push(mesh);
              g.add(mesh);
            }
            const edges = new T.LineSegments(edgeGeometry(m.faces), new T.LineBasicMaterial({ color: o.colour }));
            g.userData.edges = edges;
            g.add(edges);
            const centre = new T.Vector3().fromArray(m.center).applyMatrix4(g.matrix);
            const label = labelSprite(FacetView.objectName(o), o.colour, radius * 0.055);
            label.position.copy(centre).add(new T.Vector3(0, 0, radius * 0.16));
            root.add(label);
          }
          root.add(g);
          state.objects.push(g);
        });
        controls.target.copy(c);
        camera.near = radius / 100;
        camera.far = radius * 50;
        camera.position.copy(c).add(new T.Vector3(0, -1.45 * radius, 1.55 * radius));
        camera.updateProjectionMatrix();
        controls.update();
        highlight();
        render();
      },
      setMode(mode) {
        state.mode = mode;
        colourPoints();
        requestRender();
      },
      mode() {
        return state.mode;
      },
      select(i) {
        state.selected = i;
        highlight();
        listeners.forEach((f) => f(i, i >= 0 && state.data ? state.data.objects[i] : null));
      },
      selected() {
        return state.selected;
      },
      onSelect(f) {
        listeners.push(f);
      },
      // Where object i's centre is on the canvas (CSS pixels from its top-left), for tests and tooltips.
      screenPosition(i) {
        const g = state.objects[i];
        const d = state.data;
        if (!g || !d) return null;
        const m = d.models[d.objects[i].model];
        const p = new T.Vector3().fromArray(m.center).applyMatrix4(g.matrix).project(camera);
        const r = renderer.domElement.getBoundingClientRect();
        return { x: (p.x + 1) / 2 * r.width, y: (1 - p.y) / 2 * r.height };
      },
      // Share of canvas pixels (sampled) that differ from the background: 0 = blank.
      drawnFraction() {
        render();
        const gl = renderer.getContext();
        const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
        const px = new Uint8Array(4 * w * h);
        gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
        const bg = new T.Color(BACKGROUND);
        const br = Math.round(bg.r * 255), bgc = Math.round(bg.g * 255), bb = Math.round(bg.b * 255);
        let diff = 0, n = 0;
        for (let i = 0; i < w * h; i += 7, ++n)
          if (Math.abs(px[4 * i] - br) + Math.abs(px[4 * i + 1] - bgc) + Math.abs(px[4 * i + 2] - bb) > 24) ++diff;
        return n ? diff / n : 0;
      },
      resetView() {
        if (state.data) this.setScan(state.data, state.pts);
      },
      render,
      resize,
    };
    renderer.domElement.addEventListener('pointerdown', (e) => {
      state.down = [e.clientX, e.clientY];
    });
    renderer.domElement.addEventListener('pointerup', (e) => {
      if (!state.down || Math.hypot(e.clientX - state.down[0], e.clientY - state.down[1]) > 4) return;
      const r = renderer.domElement.getBoundingClientRect();
      const ndc = new T.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
      const ray = new T.Raycaster();
      ray.setFromCamera(ndc, camera);
      const meshes = [];
      state.objects.forEach((g) => meshes.push(...g.userData.faces));
      const hit = ray.intersectObjects(meshes, false)[0];
      viewer.select(hit ? hit.object.userData.index : -1);
    });
    resize();
    return viewer;
  };

  // The report's 3D view: data = {detail: JSON, points: base64 of the points blob}.
  FacetView.report = function (container, info, data) {
    const pts = data.points ? FacetView.decodePoints(FacetView.base64ToBuffer(data.points)) : null;
    const v = FacetView.create(container, { mode: 'object' });
    v.setScan(data.detail, pts);
    const list = document.createElement('div');
    list.className = 'fs-objects';
    (data.detail.objects || []).forEach((o, i) => {
      const b = document.createElement('button');
      b.innerHTML = '<span class="sw" style="background:' + esc(o.colour) + '"></span>' + esc(FacetView.objectName(o));
      b.onclick = () => v.select(i);
      list.appendChild(b);
    });
    const modes = document.createElement('div');
    modes.className = 'fs-modes';
    ['height', 'segment', 'object'].forEach((m) => {
      const b = document.createElement('button');
      b.textContent = 'colour: ' + m;
      b.onclick = () => v.setMode(m);
      modes.appendChild(b);
    });
    const details = document.createElement('div');
    details.className = 'fs-details';
    details.textContent = 'Click an object (in the view or above) to see its pose.';
    info.appendChild(modes);
    info.appendChild(list);
    info.appendChild(details);
    v.onSelect((i, o) => {
      details.innerHTML = o ? FacetView.objectDetailsHTML(o, data.detail) : 'Click an object to see its pose.';
    });
    window.facetReportView = v;
    return v;
  };

  window.FacetView = FacetView;
})();

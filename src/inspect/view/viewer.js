// The viewer of `nmbake view` (three.js r111, classic scripts).
//
// The low mesh comes from the embedded .glb through GLTFLoader; its normal
// map is decoded in this page's own shader exactly as `nmbake preview`
// decodes it (src/inspect/preview_render.cpp): T, N and the tangent sign
// interpolated and not normalised, B = sign * cross(N, T) per pixel,
// t = 2 rgb - 1 (y negated for green down), n = normalize(t.x T + t.y B +
// t.z N), and lit as the preview lights it (Blinn-Phong: ambient, key
// diffuse, specular exponent 40, fill, gamma 2.2). The URL's hash sets the
// state, e.g. #mode=compare&size=384&yaw=30&pitch=20&map=on&light=-0.55,0.6,0.6
// (compare: the preview's camera, the canvas alone, size x size).
/* global THREE */
(function () {
  'use strict';

  const status = document.getElementById('status');
  function setStatus(text) {
    status.textContent = text;
    document.title = 'nmbake view: ' + text;
  }
  // Console errors and warnings (three.js reports shader and texture
  // problems there) are counted and kept: the page is "ready" only without.
  const problems = [];
  ['error', 'warn'].forEach(function (level) {
    const original = console[level];
    console[level] = function () {
      problems.push(level + ': ' + Array.prototype.join.call(arguments, ' '));
      original.apply(console, arguments);
    };
  });
  window.addEventListener('error', function (e) {
    problems.push('error: ' + e.message);
    setStatus('error: ' + e.message);
  });

  function fromBase64(text) {
    const raw = atob(text.trim());
    const bytes = new Uint8Array(raw.length);
    for (let i = 0; i < raw.length; ++i) bytes[i] = raw.charCodeAt(i);
    return bytes.buffer;
  }

  const config = JSON.parse(document.getElementById('nmbake-config').textContent);
  const glbBytes = fromBase64(document.getElementById('nmbake-glb').textContent);

  // --- State, from the hash ------------------------------------------------
  const params = {};
  location.hash.replace(/^#/, '').split('&').forEach(function (pair) {
    if (!pair) return;
    const at = pair.indexOf('=');
    params[decodeURIComponent(at < 0 ? pair : pair.slice(0, at))] = at < 0 ? '' : decodeURIComponent(pair.slice(at + 1));
  });
  const compare = params.mode === 'compare';
  const view = config.view;
  const state = {
    size: params.size ? parseInt(params.size, 10) : view.size,
    yaw: params.yaw !== undefined ? parseFloat(params.yaw) : view.yaw,
    pitch: params.pitch !== undefined ? parseFloat(params.pitch) : view.pitch,
    light: params.light ? params.light.split(',').map(parseFloat) : view.light.slice(),
    normalMap: params.map !== 'off',
    show: params.show || 'lit',
    wireframe: params.wire === 'on',
    misses: params.misses === 'on',
    high: params.high || 'off',
  };
  if (compare) document.body.classList.add('compare');

  // --- Renderer, camera ----------------------------------------------------
  const canvas = document.getElementById('view');
  const renderer = new THREE.WebGLRenderer({ canvas: canvas, antialias: !compare, preserveDrawingBuffer: true });
  renderer.setPixelRatio(compare ? 1 : window.devicePixelRatio || 1);
  const bg = config.background;
  renderer.setClearColor(new THREE.Color(bg[0], bg[1], bg[2]), 1);
  const scene = new THREE.Scene();
  const centre = new THREE.Vector3().fromArray(config.framing.centre);
  const radius = Math.max(config.framing.radius, 1e-6);
  const camera = new THREE.PerspectiveCamera(30, 1, radius * 0.01, radius * 100);

  // The preview's camera (preview_draw.cpp make_camera): the bounding sphere
  // touches the edges of a 30 degree cone, with a 4% margin. Outside compare
  // mode the cone is the narrower of the two fields of view, and with the
  // high beside the low both are framed.
  const right = new THREE.Vector3();
  function placeCamera() {
    const yaw = state.yaw * Math.PI / 180, pitch = state.pitch * Math.PI / 180;
    let out;
    if (view.up === 'y') {
      out = new THREE.Vector3(Math.cos(pitch) * Math.sin(yaw), Math.sin(pitch), Math.cos(pitch) * Math.cos(yaw));
      camera.up.set(0, 1, 0);
    } else {
      out = new THREE.Vector3(Math.cos(pitch) * Math.sin(yaw), -Math.cos(pitch) * Math.cos(yaw), Math.sin(pitch));
      camera.up.set(0, 0, 1);
    }
    right.crossVectors(out.clone().negate(), camera.up).normalize();
    const beside = !compare && state.high === 'beside';
    const target = centre.clone().addScaledVector(right, beside ? 1.05 * radius : 0);
    const half = 15 * Math.PI / 180;
    let distance = 1.04 * radius / Math.sin(half);
    if (!compare) {
      const across = Math.atan(camera.aspect * Math.tan(half));  // half the horizontal field of view
      distance = Math.max(distance, 1.04 * (beside ? 2.1 : 1) * radius / Math.sin(across));
    }
    camera.position.copy(target).addScaledVector(out, distance);
    camera.lookAt(target);
    if (controls) {
      controls.target.copy(target);
      controls.update();
    }
  }
  let controls = null;
  // Outside compare mode the canvas leaves the panel's column free.
  const panelWidth = compare || window.innerWidth < 700 ? 0 : 296;
  canvas.style.marginLeft = panelWidth + 'px';
  function resize() {
    const w = compare ? state.size : window.innerWidth - panelWidth;
    const h = compare ? state.size : window.innerHeight;
    renderer.setSize(w, h, true);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  }
  resize();
  placeCamera();

  if (!compare) {
    controls = new THREE.OrbitControls(camera, canvas);
    placeCamera();
    controls.addEventListener('change', render);
    window.addEventListener('resize', function () { resize(); placeCamera(); render(); });
  }

  // --- The shader: nmbake's decode and the preview's lights ----------------
  const vertexShader = [
    'attribute vec4 tangent;',
    'uniform float uvLayout;',
    'varying vec3 vN;',
    'varying vec4 vT;',
    'varying vec2 vUv;',
    'varying vec3 vViewPosition;',
    'void main() {',
    '  // View space (a rotation of object space: the decode is linear, cross() keeps its sign).',
    '  vN = normalMatrix * normal;',
    '  vT = vec4(normalMatrix * tangent.xyz, tangent.w);',
    '  vUv = uv;',
    '  vec4 mv = modelViewMatrix * vec4(position, 1.0);',
    '  vViewPosition = mv.xyz;',
    '  gl_Position = uvLayout > 0.5 ? vec4(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, 0.0, 1.0) : projectionMatrix * mv;',
    '}',
  ].join('\n');
  const fragmentShader = [
    'uniform sampler2D normalMap;',
    'uniform sampler2D shownMap;',
    'uniform sampler2D missMap;',
    'uniform float useNormalMap;',
    'uniform float hasTangents;',
    'uniform float greenDown;',
    'uniform float showMap;', // 0: lit; 1: colour map as is; 2: scalar map in false colour
    'uniform float useMisses;',
    'uniform vec3 keyLight;',
    'uniform vec3 fillLight;',
    'varying vec3 vN;',
    'varying vec4 vT;',
    'varying vec2 vUv;',
    'varying vec3 vViewPosition;',
    'vec3 shade(vec3 n, vec3 toEye) {',
    '  vec3 albedo = vec3(0.80, 0.78, 0.74);',
    '  float diffuse = max(dot(n, keyLight), 0.0);',
    '  float fill = max(dot(n, fillLight), 0.0);',
    '  float specular = 0.0;',
    '  if (diffuse > 0.0) specular = pow(max(dot(n, normalize(keyLight + toEye)), 0.0), 40.0);',
    '  vec3 linear = albedo * (0.04 + 0.82 * diffuse + 0.2 * fill) + vec3(0.3 * specular);',
    '  return pow(clamp(linear, 0.0, 1.0), vec3(1.0 / 2.2));',
    '}',
    '// The preview heat ramp: dark blue, green, yellow, red.',
    'vec3 ramp(float f) {',
    '  f = clamp(f, 0.0, 1.0);',
    '  vec3 a = vec3(0.05, 0.08, 0.35), b = vec3(0.1, 0.6, 0.35), c = vec3(0.95, 0.85, 0.2), d = vec3(0.85, 0.1, 0.1);',
    '  return f < 0.33 ? mix(a, b, f / 0.33) : f < 0.66 ? mix(b, c, (f - 0.33) / 0.33) : mix(c, d, (f - 0.66) / 0.34);',
    '}',
    'void main() {',
    '  vec3 toEye = normalize(-vViewPosition);',
    '  vec3 N = vN;',
    '  float lN = length(N);',
    '  vec3 lowNormal = lN > 1e-12 ? N / lN : toEye;',
    '  vec3 colour;',
    '  if (showMap > 1.5) {',
    '    colour = ramp(texture2D(shownMap, vUv).r);',
    '  } else if (showMap > 0.5) {',
    '    colour = texture2D(shownMap, vUv).rgb;',
    '  } else {',
    '    vec3 n = lowNormal;',
    '    if (useNormalMap > 0.5 && hasTangents > 0.5) {',
    '      vec3 t = texture2D(normalMap, vUv).rgb * 2.0 - 1.0;',
    '      if (greenDown > 0.5) t.y = -t.y;',
    '      vec3 T = vT.xyz;',
    '      float s = vT.w < 0.0 ? -1.0 : 1.0;',
    '      vec3 raw = t.x * T + t.y * (s * cross(N, T)) + t.z * N;',
    '      float l = length(raw);',
    '      if (l > 1e-12) n = raw / l;',
    '    }',
    '    colour = shade(n, toEye);',
    '  }',
    '  if (useMisses > 0.5 && texture2D(missMap, vUv).r > 0.5) colour = vec3(0.9, 0.1, 0.85);',
    '  gl_FragColor = vec4(colour, 1.0);',
    '}',
  ].join('\n');

  const lights = { key: new THREE.Vector3(), fill: new THREE.Vector3() };
  // Camera space, as the preview (make_lights): the fill mirrors the key.
  function updateLights() {
    const k = new THREE.Vector3().fromArray(state.light).normalize();
    lights.key.copy(k);
    lights.fill.set(-k.x, -0.3 * k.y, Math.max(k.z, 0.4)).normalize();
  }
  updateLights();

  const blank = new THREE.DataTexture(new Uint8Array([128, 128, 255, 255]), 1, 1, THREE.RGBAFormat);
  blank.needsUpdate = true;
  const black = new THREE.DataTexture(new Uint8Array([0, 0, 0, 255]), 1, 1, THREE.RGBAFormat);
  black.needsUpdate = true;

  function makeMaterial(tile, hasTangents) {
    return new THREE.ShaderMaterial({
      vertexShader: vertexShader,
      fragmentShader: fragmentShader,
      uniforms: {
        normalMap: { value: blank },
        shownMap: { value: black },
        missMap: { value: black },
        useNormalMap: { value: 1 },
        hasTangents: { value: hasTangents ? 1 : 0 },
        greenDown: { value: 0 },
        showMap: { value: 0 },
        useMisses: { value: 0 },
        uvLayout: { value: 0 },
        keyLight: { value: lights.key },
        fillLight: { value: lights.fill },
      },
      polygonOffset: true,
      polygonOffsetFactor: 1,
      polygonOffsetUnits: 1,
      side: THREE.FrontSide,
    });
  }

  // Textures as the preview samples: bilinear, clamped, no mipmaps.
  function asPreviewSamples(texture) {
    texture.minFilter = THREE.LinearFilter;
    texture.magFilter = THREE.LinearFilter;
    texture.generateMipmaps = false;
    texture.wrapS = texture.wrapT = THREE.ClampToEdgeWrapping;
    texture.flipY = false;  // glTF's UV origin is the image's top left
    texture.needsUpdate = true;
    return texture;
  }

  // --- Maps: from the glTF's materials, or the page's own list -----------------
  const scalarKinds = ['ao', 'height', 'curvature', 'thickness', 'miss', 'roughness', 'metallic', 'opacity'];
  const pageTextures = {};  // "map index/tile" -> texture
  const pending = [];
  config.maps.forEach(function (map, index) {
    Object.keys(map.tiles).forEach(function (tile) {
      const entry = map.tiles[tile];
      if (!entry.png) return;
      pending.push(new Promise(function (resolve, reject) {
        new THREE.TextureLoader().load('data:image/png;base64,' + entry.png, function (texture) {
          pageTextures[index + '/' + tile] = asPreviewSamples(texture);
          resolve();
        }, undefined, function () { reject(new Error('map ' + map.file + ' tile ' + tile + ' did not decode')); });
      }));
    });
  });

  const lows = [];  // { mesh, tile, material, pbr, wire }
  const highs = [];
  const slotOf = { normal: 'normalMap', occlusion: 'aoMap', base_color: 'map', emissive: 'emissiveMap' };

  function mapTexture(index, tile) {
    const map = config.maps[index];
    if (map.slot) {
      const low = lows.find(function (l) { return l.tile === tile; });
      return low && low.pbr[slotOf[map.slot]] ? low.pbr[slotOf[map.slot]] : null;
    }
    return pageTextures[index + '/' + tile] || null;
  }

  function indexOfKind(kind) {
    for (let i = 0; i < config.maps.length; ++i) if (config.maps[i].kind === kind) return i;
    return -1;
  }

  // --- The UI --------------------------------------------------------------
  const showSelect = document.getElementById('show');
  function addOption(value, text) {
    const o = document.createElement('option');
    o.value = value;
    o.textContent = text;
    showSelect.appendChild(o);
  }
  addOption('lit', 'lit (nmbake\'s decode, the preview\'s lights)');
  addOption('pbr', 'three.js PBR (the glTF material as r111 shows it)');
  config.maps.forEach(function (map, i) {
    addOption('map' + i, map.kind + ': ' + map.file + (scalarKinds.indexOf(map.kind) >= 0 ? ' (false colour)' : ''));
  });
  addOption('uv', 'UV layout (normal map behind)');
  showSelect.value = state.show;

  function bindCheckbox(id, key) {
    const box = document.getElementById(id);
    box.checked = state[key];
    box.addEventListener('change', function () { state[key] = box.checked; apply(); });
  }
  bindCheckbox('normal-map', 'normalMap');
  bindCheckbox('wireframe', 'wireframe');
  bindCheckbox('misses', 'misses');
  showSelect.addEventListener('change', function () { state.show = showSelect.value; apply(); });
  const highSelect = document.getElementById('high');
  highSelect.value = state.high;
  highSelect.addEventListener('change', function () {
    state.high = highSelect.value;
    placeCamera();
    apply();
  });
  if (!config.high) highSelect.disabled = true;
  if (indexOfKind('miss') < 0) document.getElementById('misses').disabled = true;

  // Dragging the light: the pointer on a hemisphere facing the viewer.
  const dragLight = document.getElementById('drag-light');
  let dragging = false;
  function lightFromPointer(e) {
    const r = canvas.getBoundingClientRect();
    const x = 2 * (e.clientX - r.left) / r.width - 1, y = 1 - 2 * (e.clientY - r.top) / r.height;
    const d = Math.min(1, x * x + y * y);
    state.light = [x, y, Math.sqrt(Math.max(0.02, 1 - d))];
    updateLights();
    render();
  }
  dragLight.addEventListener('change', function () { if (controls) controls.enabled = !dragLight.checked; });
  canvas.addEventListener('pointerdown', function (e) { if (dragLight.checked) { dragging = true; lightFromPointer(e); } });
  canvas.addEventListener('pointermove', function (e) { if (dragging) lightFromPointer(e); });
  window.addEventListener('pointerup', function () { dragging = false; });

  // --- Figures and warnings ------------------------------------------------
  function addFigure(name, value) {
    const row = document.createElement('tr');
    const a = document.createElement('td'), b = document.createElement('td');
    a.textContent = name;
    b.textContent = value;
    row.appendChild(a);
    row.appendChild(b);
    document.getElementById('figures').appendChild(row);
  }
  function warn(text) {
    const d = document.createElement('div');
    d.className = 'warning';
    d.textContent = text;
    document.getElementById('warnings').appendChild(d);
  }
  document.getElementById('heading').textContent = 'nmbake view: ' + config.low;
  let greenDown = false;
  const report = config.report;
  if (report) {
    const enc = report.encoding || {};
    if (enc.green === 'down') {
      greenDown = true;
      warn('The report says green down (DirectX): the page negates green to decode it; a glTF viewer expects green up.');
    }
    const other = [];
    if (enc.bitangent && enc.bitangent !== 'pixel') other.push('bitangent ' + enc.bitangent);
    if (enc.tbn && enc.tbn !== 'raw') other.push('tbn ' + enc.tbn);
    if (enc.blue && enc.blue !== 'stored') other.push('blue ' + enc.blue);
    if (enc.preset && enc.preset !== 'None' && enc.preset !== 'none') other.push('preset ' + enc.preset);
    if (other.length) {
      warn('The map was baked for another decode (' + other.join(', ') + '); this page decodes MikkTSpace with a ' +
           'per-pixel bitangent and a raw frame, so small differences are expected.');
    }
    const rays = report.rays || {};
    addFigure('map', report.width + ' x ' + report.height + ', ' + report.samples_per_texel + ' spp');
    addFigure('rays', rays.rays);
    addFigure('misses', rays.misses + ' (' + (100 * (rays.miss_rate || 0)).toFixed(3) + '%)');
    if (report.coverage) addFigure('covered texels', (100 * report.coverage.fraction).toFixed(1) + '%');
    if (report.distances) addFigure('front / back', report.distances.front.toPrecision(4) + ' / ' +
                                    report.distances.back.toPrecision(4) + (report.distances.estimated ? ' (auto)' : ''));
    addFigure('bake time', (report.total_seconds || 0).toFixed(2) + ' s');
    addFigure('low / high triangles', report.low_triangles + ' / ' + report.high_triangles);
    const note = document.createElement('div');
    note.className = 'note';
    note.textContent = 'The report holds counts, not a per-texel miss map: bake --map miss and pass it to show misses.';
    document.getElementById('panel').appendChild(note);
  }
  if (config.high) {
    addFigure('high shown', config.high.shown + ' of ' + config.high.triangles + ' triangles' +
              (config.high.shown < config.high.triangles ? ' (vertex clustering)' : ''));
  }

  // --- Rendering -----------------------------------------------------------
  function apply() {
    const shownIndex = state.show.indexOf('map') === 0 ? parseInt(state.show.slice(3), 10) : -1;
    const missIndex = indexOfKind('miss');
    const normalIndex = indexOfKind('normal');
    lows.forEach(function (l) {
      const u = l.material.uniforms;
      const normal = normalIndex >= 0 ? mapTexture(normalIndex, l.tile) : null;
      u.normalMap.value = normal || blank;
      u.useNormalMap.value = state.normalMap && normal ? 1 : 0;
      u.greenDown.value = greenDown ? 1 : 0;
      u.uvLayout.value = state.show === 'uv' ? 1 : 0;
      u.showMap.value = 0;
      if (shownIndex >= 0) {
        const t = mapTexture(shownIndex, l.tile);
        u.shownMap.value = t || black;
        u.showMap.value = scalarKinds.indexOf(config.maps[shownIndex].kind) >= 0 ? 2 : 1;
      } else if (state.show === 'uv') {
        u.shownMap.value = normal || black;
        u.showMap.value = 1;
      }
      const miss = missIndex >= 0 ? mapTexture(missIndex, l.tile) : null;
      u.missMap.value = miss || black;
      u.useMisses.value = state.misses && miss ? 1 : 0;
      l.mesh.material = state.show === 'pbr' ? l.pbr : l.material;
      l.mesh.visible = state.high !== 'only' || state.show === 'uv';
      l.wire.visible = state.wireframe && state.show !== 'uv';
      l.uvWire.visible = state.show === 'uv';
    });
    highs.forEach(function (h) {
      h.visible = state.high !== 'off' && state.show !== 'uv';
      h.position.copy(right).multiplyScalar(state.high === 'beside' ? 2.1 * radius : 0);
    });
    scene.background = null;
    render();
  }

  function render() {
    if (state.show === 'uv') {
      const s = Math.min(canvas.width, canvas.height);
      renderer.setViewport(0, 0, s / renderer.getPixelRatio(), s / renderer.getPixelRatio());
    } else {
      renderer.setViewport(0, 0, canvas.width / renderer.getPixelRatio(), canvas.height / renderer.getPixelRatio());
    }
    renderer.render(scene, camera);
  }

  // --- Loading -------------------------------------------------------------
  function loadGlb() {
    return new Promise(function (resolve, reject) {
      new THREE.GLTFLoader().parse(glbBytes, '', resolve, function (e) { reject(e instanceof Error ? e : new Error(String(e))); });
    });
  }

  function fromBase64Array(Type, text) {
    return new Type(fromBase64(text));
  }

  Promise.all([loadGlb()].concat(pending)).then(function (results) {
    const gltf = results[0];
    // Lights for the PBR view only (the lit view computes its own).
    const sun = new THREE.DirectionalLight(0xffffff, 0.9);
    camera.add(sun);
    sun.position.set(state.light[0], state.light[1], state.light[2]);
    scene.add(camera);
    scene.add(new THREE.HemisphereLight(0xffffff, 0x404040, 0.25));
    gltf.scene.updateMatrixWorld(true);
    gltf.scene.traverse(function (object) {
      if (!object.isMesh) return;
      const name = object.material && object.material.name ? object.material.name : 'tile_1001';
      const tile = name.replace(/^tile_/, '');
      const pbr = object.material;
      ['normalMap', 'aoMap', 'map', 'emissiveMap'].forEach(function (slot) {
        if (pbr[slot]) asPreviewSamples(pbr[slot]);
      });
      const material = makeMaterial(tile, object.geometry.attributes.tangent !== undefined);
      const wire = new THREE.LineSegments(new THREE.WireframeGeometry(object.geometry),
                                          new THREE.LineBasicMaterial({ color: 0x101010 }));
      object.add(wire);
      // The UV layout: the triangles' edges in UV space.
      const uvGeometry = new THREE.BufferGeometry();
      const uvs = uvEdges(object.geometry);
      uvGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(uvs.count * 3), 3));
      uvGeometry.setAttribute('uv', uvs);
      const uvWire = new THREE.LineSegments(uvGeometry, new THREE.ShaderMaterial({
        vertexShader: 'void main() { gl_Position = vec4(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, 0.0, 1.0); }',
        fragmentShader: 'void main() { gl_FragColor = vec4(0.05, 0.05, 0.05, 1.0); }',
      }));
      uvWire.frustumCulled = false;
      object.add(uvWire);
      object.frustumCulled = false;
      lows.push({ mesh: object, tile: tile, material: material, pbr: pbr, wire: wire, uvWire: uvWire });
    });
    scene.add(gltf.scene);
    if (config.high) {
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(fromBase64Array(Float32Array, config.high.positions), 3));
      g.setAttribute('normal', new THREE.BufferAttribute(fromBase64Array(Float32Array, config.high.normals), 3));
      g.setAttribute('uv', new THREE.BufferAttribute(new Float32Array(g.attributes.position.count * 2), 2));
      g.setIndex(new THREE.BufferAttribute(fromBase64Array(Uint32Array, config.high.indices), 1));
      const high = new THREE.Mesh(g, makeMaterial('high', false));
      highs.push(high);
      scene.add(high);
    }
    apply();
    if (config.served) {
      // The maps as they are on disk now, then whenever they change.
      return reloadMaps(0).then(function () {
        setStatus(problems.length ? 'console: ' + problems.join(' | ') : 'ready');
        setInterval(poll, 1000);
      });
    }
    setStatus(problems.length ? 'console: ' + problems.join(' | ') : 'ready');
  }).catch(function (e) {
    setStatus('error: ' + (e && e.message ? e.message : e));
  });

  // --serve: /state counts the changes of the map files; each change
  // fetches every map again (/map/I/TILE.png) and swaps the textures.
  let version = 0;
  let reloads = 0;
  let polling = false;
  function poll() {
    if (polling) return;
    polling = true;
    fetch('state', { cache: 'no-store' }).then(function (r) { return r.json(); }).then(function (s) {
      if (s.version === version) return null;
      return reloadMaps(s.version);
    }).catch(function (e) {
      status.textContent = 'server: ' + e.message;
    }).then(function () { polling = false; });
  }
  function loadTexture(url) {
    return new Promise(function (resolve, reject) {
      new THREE.TextureLoader().load(url, resolve, undefined, function () { reject(new Error(url + ' did not load')); });
    });
  }
  function reloadMaps(newVersion) {
    const jobs = [];
    config.maps.forEach(function (map, index) {
      Object.keys(map.tiles).forEach(function (tile) {
        jobs.push(loadTexture('map/' + index + '/' + tile + '.png?v=' + newVersion).then(function (texture) {
          asPreviewSamples(texture);
          if (map.slot) {
            const low = lows.find(function (l) { return l.tile === tile; });
            if (low) {
              if (low.pbr[slotOf[map.slot]]) low.pbr[slotOf[map.slot]].dispose();
              low.pbr[slotOf[map.slot]] = texture;
              low.pbr.needsUpdate = true;
            }
          } else {
            if (pageTextures[index + '/' + tile]) pageTextures[index + '/' + tile].dispose();
            pageTextures[index + '/' + tile] = texture;
          }
        }));
      });
    });
    return Promise.all(jobs).then(function () {
      version = newVersion;
      if (newVersion > 0) {
        ++reloads;
        setStatus('ready, maps reloaded ' + reloads + (reloads === 1 ? ' time' : ' times'));
      }
      apply();
    });
  }

  // The triangles' edges as line segments of their UVs.
  function uvEdges(geometry) {
    const index = geometry.index.array, uv = geometry.attributes.uv.array;
    const out = new Float32Array(index.length * 4);
    let o = 0;
    for (let t = 0; t < index.length; t += 3) {
      for (let k = 0; k < 3; ++k) {
        const a = index[t + k], b = index[t + (k + 1) % 3];
        out[o++] = uv[2 * a]; out[o++] = uv[2 * a + 1];
        out[o++] = uv[2 * b]; out[o++] = uv[2 * b + 1];
      }
    }
    return new THREE.BufferAttribute(out, 2);
  }
})();

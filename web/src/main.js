// The page of `gissar view` (docs/view.md): an OpenLayers map in EPSG:4326 of what /api/view.json describes.
// Everything is served by the local server: no tile server, nothing fetched from elsewhere.
import 'ol/ol.css';
import './style.css';
import Map from 'ol/Map.js';
import View from 'ol/View.js';
import GeoJSON from 'ol/format/GeoJSON.js';
import VectorLayer from 'ol/layer/Vector.js';
import ImageLayer from 'ol/layer/Image.js';
import VectorSource from 'ol/source/Vector.js';
import ImageStatic from 'ol/source/ImageStatic.js';
import {Circle, Fill, RegularShape, Stroke, Style, Text} from 'ol/style.js';
import {createEmpty, extend, isEmpty} from 'ol/extent.js';
import {defaults as defaultControls, ScaleLine} from 'ol/control.js';
import {fromLonLat, transformExtent} from 'ol/proj.js';

const body = document.body;
const $ = (id) => document.getElementById(id);
// The view is Web Mercator (true shapes); the server's GeoJSON and rendered images are in WGS84.
const format = new GeoJSON({dataProjection: 'EPSG:4326', featureProjection: 'EPSG:3857'});

const state = {description: null, selected: null, imageLayer: null, maskLayer: null, requests: 0};

async function getJSON(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
  return response.json();
}

function hexToRgba(hex, alpha) {
  const n = parseInt(hex.slice(1), 16);
  return `rgba(${(n >> 16) & 255},${(n >> 8) & 255},${n & 255},${alpha})`;
}

const map = new Map({
  target: 'map',
  controls: defaultControls({attribution: false}).extend([new ScaleLine()]),
  view: new View({center: [0, 0], zoom: 2}),
});

const baseLayer = new ImageLayer({className: 'base', zIndex: 0});
// The scene's classes from above (water, forest, urban, road, building, sea; bare terrain transparent).
const classLayer = new ImageLayer({className: 'classes', zIndex: 1, opacity: 0.75});
const footprintSource = new VectorSource();
const colours = {};
const footprintStyles = {};
function footprintStyle(feature) {
  const status = feature.get('status');
  const selected = state.selected === feature;
  const key = status + (selected ? ':sel' : '');
  if (!footprintStyles[key]) {
    const colour = colours[status] || '#888888';
    footprintStyles[key] = new Style({
      stroke: new Stroke({color: selected ? '#ffffff' : colour, width: selected ? 3 : 1.5,
                          lineDash: status === 'missing' || status === 'skipped' ? [6, 4] : undefined}),
      fill: new Fill({color: hexToRgba(colour, status === 'missing' ? 0.35 : 0.18)}),
    });
  }
  return footprintStyles[key];
}
const footprintLayer = new VectorLayer({source: footprintSource, style: footprintStyle, zIndex: 2});
const routeSource = new VectorSource();
const routeLayer = new VectorLayer({
  source: routeSource, zIndex: 4,
  style: new Style({stroke: new Stroke({color: '#202020', width: 2.5})}),
});
const arrowSource = new VectorSource();
const arrowStyles = {};
const arrowLayer = new VectorLayer({
  source: arrowSource, zIndex: 5,
  style: (feature) => {
    const heading = feature.get('heading_deg') || 0;
    const key = `${heading}:${feature.get('status')}`;
    if (!arrowStyles[key]) {
      arrowStyles[key] = new Style({image: new RegularShape({
        points: 3, radius: 7, rotation: (heading * Math.PI) / 180, rotateWithView: true,
        fill: new Fill({color: colours[feature.get('status')] || '#202020'}),
        stroke: new Stroke({color: '#ffffff', width: 1}),
      })});
    }
    return arrowStyles[key];
  },
});
const markerColours = {prior: '#f0a000', fix: '#2e9d3a', truth: '#d12f1f'};
const markerSource = new VectorSource();
const markerLayer = new VectorLayer({
  source: markerSource, zIndex: 7,
  style: (feature) => {
    const role = feature.get('role');
    if (role === 'trial') {
      return new Style({image: new Circle({radius: 4, fill: new Fill({color: feature.get('success') ? '#2e9d3a' : '#d12f1f'}),
                                           stroke: new Stroke({color: '#ffffff', width: 1})})});
    }
    if (role === 'success_radius') {
      return new Style({stroke: new Stroke({color: '#d12f1f', width: 2, lineDash: [6, 4]})});
    }
    if (role === 'ellipse95') {
      return new Style({stroke: new Stroke({color: '#2e9d3a', width: 2, lineDash: [4, 3]}),
                        fill: new Fill({color: 'rgba(46,157,58,0.12)'})});
    }
    return new Style({
      image: new Circle({radius: 7, fill: new Fill({color: markerColours[role] || '#000'}),
                         stroke: new Stroke({color: '#ffffff', width: 2})}),
      text: new Text({text: feature.get('label') || role, offsetY: -16, font: '12px sans-serif',
                      fill: new Fill({color: '#111'}), stroke: new Stroke({color: '#fff', width: 3})}),
    });
  },
});
map.getLayers().extend([baseLayer, classLayer, footprintLayer, routeLayer, arrowLayer, markerLayer]);

function staticLayer(url, extent, zIndex, opacity, className) {
  const source = new ImageStatic({url, imageExtent: extent, projection: 'EPSG:4326', interpolate: true});
  return new ImageLayer({source, zIndex, opacity, className});
}

async function showBase(base) {
  if (!base || !base.hillshade) return;
  const info = await getJSON(base.hillshade_info);
  baseLayer.setSource(new ImageStatic({url: base.hillshade, imageExtent: info.extent, projection: 'EPSG:4326'}));
  return transformExtent(info.extent, 'EPSG:4326', 'EPSG:3857');
}

// The scene's class layer and its legend; resolves to its extent (EPSG:3857) once the picture has loaded.
async function showClasses(base) {
  if (!base || !base.classes) return null;
  const info = await getJSON(base.classes_info);
  const source = new ImageStatic({url: base.classes, imageExtent: info.extent, projection: 'EPSG:4326'});
  const loaded = new Promise((resolve) => {
    source.once('imageloadend', () => resolve(true));
    source.once('imageloaderror', () => resolve(false));
  });
  classLayer.setSource(source);
  $('classes-row').hidden = false;
  $('class-legend').hidden = false;
  $('class-legend').innerHTML = 'scene classes: ' + Object.entries(info.legend || {})
    .map(([name, colour]) => `<span class="swatch" style="background:${colour}"></span>${name}`).join(' ');
  body.dataset.classes = String(Object.keys(info.legend || {}).length);
  loaded.then((ok) => { body.dataset.classesLoaded = ok ? '1' : 'error'; });
  return transformExtent(info.extent, 'EPSG:4326', 'EPSG:3857');
}

function setMetadata(object) {
  $('metadata').textContent = JSON.stringify(object, null, 1);
}

function setColourbar(info) {
  if (!info || !info.db_range) { $('colourbar').hidden = true; return; }
  $('colourbar').hidden = false;
  $('cb-lo').textContent = `${info.db_range[0].toFixed(1)}`;
  $('cb-hi').textContent = `${info.db_range[1].toFixed(1)} dB`;
  $('cb-unit').textContent = 'sigma0';
  $('colourbar').title = info.unit;
}

function imageLoaded(layer) {
  return new Promise((resolve) => {
    const source = layer.getSource();
    source.once('imageloadend', () => resolve(true));
    source.once('imageloaderror', () => resolve(false));
  });
}

async function showImage(image, label) {
  for (const key of ['imageLayer', 'maskLayer']) {
    if (state[key]) { map.removeLayer(state[key]); state[key] = null; }
  }
  body.dataset.imageLoaded = '0';
  $('mask-row').hidden = !image.mask;
  $('quicklook').hidden = !(image.quicklook || image.thumbnail);
  if (image.quicklook || image.thumbnail) $('quicklook').src = image.quicklook || image.thumbnail;
  if (!image.render) { setColourbar(null); $('selection').textContent = `${label}: no image (files missing)`; return; }
  const request = ++state.requests;
  const info = await getJSON(image.render_info);
  if (request !== state.requests) return;
  setColourbar(info);
  state.imageExtent = info.extent;
  state.imageLayer = staticLayer(image.render, info.extent, 3, Number($('opacity').value), 'image');
  const loaded = imageLoaded(state.imageLayer);  // listening before the layer can load
  map.addLayer(state.imageLayer);
  if (image.mask) {
    const maskInfo = await getJSON(image.mask.replace(/\.png$/, '.json'));
    state.maskLayer = staticLayer(image.mask, maskInfo.extent, 6, 1, 'mask');
    state.maskLayer.setVisible($('mask').checked);
    map.addLayer(state.maskLayer);
  }
  const ok = await loaded;
  if (request !== state.requests) return;
  map.once('rendercomplete', () => {
    if (state.clickedAt) body.dataset.imageMs = String(Math.round(performance.now() - state.clickedAt));
    body.dataset.imageLoaded = ok ? '1' : 'error';
  });
  map.render();
}

function select(feature) {
  const previous = state.selected;
  state.selected = feature;
  if (previous) previous.changed();
  if (!feature) return;
  feature.changed();
  const p = feature.getProperties();
  body.dataset.selected = p.id;
  const shown = {id: p.id, status: p.status, reason: p.reason, heading_deg: p.heading_deg,
                 pose_lon_lat_deg: [p.lon_deg, p.lat_deg], distance_m: p.distance_m,
                 scene_centre_lon_lat_deg: p.center_lonlat_deg, time_utc: p.time_utc,
                 options_sha256: p.options_sha256, files: p.files,
                 geocoded: (p.image || {}).geocoded};
  $('selection').textContent = `pose ${p.id} (${p.status}${p.reason ? ': ' + p.reason : ''})`;
  setMetadata(shown);
  showImage(p.image || {}, p.id).catch((e) => { $('selection').textContent = String(e); });
}

// 'click', not 'singleclick' (which waits 250 ms for a double click): the image follows at once.
map.on('click', (event) => {
  state.clickedAt = performance.now();
  let hit = null;
  map.forEachFeatureAtPixel(event.pixel, (feature) => { hit = feature; return true; },
                            {layerFilter: (layer) => layer === footprintLayer});
  if (hit) select(hit);
});

$('opacity').addEventListener('input', () => {
  if (state.imageLayer) state.imageLayer.setOpacity(Number($('opacity').value));
});
$('mask').addEventListener('change', () => {
  if (state.maskLayer) state.maskLayer.setVisible($('mask').checked);
  map.once('rendercomplete', () => { body.dataset.maskShown = $('mask').checked ? '1' : '0'; });
  map.render();
});
$('classes-toggle').addEventListener('change', () => {
  classLayer.setVisible($('classes-toggle').checked);
});
$('footprints-toggle').addEventListener('change', () => {
  footprintLayer.setVisible($('footprints-toggle').checked);
  arrowLayer.setVisible($('footprints-toggle').checked);
});

function legend(description) {
  const counts = description.counts || {};
  const items = Object.entries(description.status_colours)
    .filter(([status]) => counts[status] || description.kind === 'corridor')
    .map(([status, colour]) => `<span class="swatch" style="background:${colour}"></span>${status}` +
                               (description.kind === 'corridor' ? ` ${counts[status] || 0}` : ''));
  if (description.kind === 'evaluate') {
    $('legend').innerHTML = '<span class="swatch round" style="background:#2e9d3a"></span>fix (success) ' +
      '<span class="swatch round" style="background:#d12f1f"></span>fix (failure) ' +
      '<span class="swatch round" style="background:#d12f1f"></span>truth ' +
      '<span class="swatch ellipse" style="border-color:#d12f1f"></span>success radius';
  } else if (description.kind === 'locate') {
    $('legend').innerHTML = Object.entries(markerColours)
      .map(([role, colour]) => `<span class="swatch round" style="background:${colour}"></span>${role}`)
      .join(' ') + ' <span class="swatch ellipse"></span>95 % ellipse';
  } else {
    $('legend').innerHTML = items.join(' ');
  }
}

async function main() {
  const description = await getJSON('/api/view.json');
  state.description = description;
  Object.assign(colours, description.status_colours);
  $('title').textContent = description.title;
  $('kind').textContent = `${description.kind}: ${description.source}`;
  document.title = `gissar view: ${description.title}`;
  legend(description);
  const extent = createEmpty();
  if (description.footprints) {
    const features = format.readFeatures(description.footprints);
    footprintSource.addFeatures(features);
    if (features.length) extend(extent, footprintSource.getExtent());
  }
  if (description.route) routeSource.addFeature(format.readFeature(description.route));
  if (description.arrows) arrowSource.addFeatures(format.readFeatures(description.arrows));
  if (description.markers) markerSource.addFeatures(format.readFeatures(description.markers));
  if (description.ellipse) markerSource.addFeature(format.readFeature(description.ellipse));
  if (markerSource.getFeatures().length) extend(extent, markerSource.getExtent());
  if (routeSource.getFeatures().length) extend(extent, routeSource.getExtent());
  body.dataset.footprints = String(footprintSource.getFeatures().length);
  body.dataset.markers = String(markerSource.getFeatures()
    .filter((f) => !['ellipse95', 'success_radius', 'trial'].includes(f.get('role'))).length);
  body.dataset.trials = String(markerSource.getFeatures().filter((f) => f.get('role') === 'trial').length);
  body.dataset.poses = String(description.poses || 0);
  setMetadata(description.metadata || {});
  let baseExtent = null;
  try {
    baseExtent = await showBase(description.base);
  } catch (e) {
    $('kind').textContent += ` (no hillshade: ${e.message})`;
  }
  try {
    const classExtent = await showClasses(description.base);
    if (!baseExtent) baseExtent = classExtent;
  } catch (e) {
    $('kind').textContent += ` (no scene classes: ${e.message})`;
  }
  if (description.image) {
    await showImage(description.image, description.title);
    if (isEmpty(extent) && state.imageExtent) extend(extent, transformExtent(state.imageExtent, 'EPSG:4326', 'EPSG:3857'));
  }
  if (isEmpty(extent) && baseExtent) extend(extent, baseExtent);
  if (!isEmpty(extent)) {
    const span = Math.max(extent[2] - extent[0], extent[3] - extent[1], 0.002);
    const pad = span * 0.15;
    map.getView().fit([extent[0] - pad, extent[1] - pad, extent[2] + pad, extent[3] + pad],
                      {size: map.getSize()});
  }
  if (description.composite) {
    $('quicklook').src = description.composite;
    $('quicklook').hidden = false;
  }
  map.once('rendercomplete', () => {
    body.dataset.readyMs = String(Math.round(performance.now()));  // since navigation start
    body.dataset.ready = '1';
  });
  map.render();
}

// For the tests and the benchmark (tests/view_browser_test.py): the map, its composite canvas and its layers.
window.gissarView = {
  map, footprintSource, markerSource, classLayer,
  pixelOf: (lon, lat) => map.getPixelFromCoordinate(fromLonLat([lon, lat])),
  composite: () => {
    const size = map.getSize();
    const canvas = document.createElement('canvas');
    const ratio = window.devicePixelRatio || 1;
    canvas.width = Math.round(size[0] * ratio);
    canvas.height = Math.round(size[1] * ratio);
    const context = canvas.getContext('2d', {willReadFrequently: true});
    context.fillStyle = '#ffffff';
    context.fillRect(0, 0, canvas.width, canvas.height);
    for (const layerCanvas of map.getViewport().querySelectorAll('.ol-layers canvas')) {
      if (layerCanvas.width === 0) continue;
      const opacity = layerCanvas.parentNode.style.opacity || layerCanvas.style.opacity;
      context.globalAlpha = opacity === '' ? 1 : Number(opacity);
      const transform = layerCanvas.style.transform;
      const m = transform && transform.match(/^matrix\(([^(]*)\)$/);
      if (m) {
        context.setTransform(...m[1].split(',').map(Number));
      } else {
        context.setTransform(1, 0, 0, 1, 0, 0);
      }
      context.drawImage(layerCanvas, 0, 0);
    }
    context.globalAlpha = 1;
    context.setTransform(1, 0, 0, 1, 0, 0);
    return {context, ratio};
  },
};

main().catch((e) => {
  $('selection').textContent = `error: ${e.message}`;
  body.dataset.ready = 'error';
  throw e;
});

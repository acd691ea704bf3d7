// Pictures of a checkerboard seen by a known camera, made in the test: every pixel (2 x 2
// samples) is undistorted through the camera's intrinsics (OpenCV's k1 k2 p1 p2 k3), its ray met
// with the board's plane, and the board's colour taken there. Written as 8-bit grey PNGs.
'use strict';
const fs = require('node:fs');
const zlib = require('node:zlib');

// The intrinsics of an OpenCV FileStorage XML (camera_matrix, distortion_coefficients).
function readIntrinsics(file) {
  const text = fs.readFileSync(file, 'utf8');
  const numbers = (name) => {
    const m = new RegExp(`<${name}[^>]*>[\\s\\S]*?<data>([\\s\\S]*?)</data>`).exec(text);
    if (!m) throw new Error(`${file}: no ${name}`);
    return m[1].trim().split(/\s+/).map(Number);
  };
  const k = numbers('camera_matrix');
  const d = [...numbers('distortion_coefficients'), 0, 0, 0, 0, 0].slice(0, 5);
  const w = /<image_width>\s*(\d+)/.exec(text);
  const hh = /<image_height>\s*(\d+)/.exec(text);
  return { fx: k[0], fy: k[4], cx: k[2], cy: k[5], d, width: w ? Number(w[1]) : 640, height: hh ? Number(hh[1]) : 480 };
}

// Normalised, undistorted image coordinates of pixel (u, v) (as cv::undistortPoints).
function undistort(cam, u, v) {
  const [k1, k2, p1, p2, k3] = cam.d;
  const xd = (u - cam.cx) / cam.fx;
  const yd = (v - cam.cy) / cam.fy;
  let x = xd;
  let y = yd;
  for (let i = 0; i < 12; i += 1) {
    const r2 = x * x + y * y;
    const radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
    const dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
    x = (xd - dx) / radial;
    y = (yd - dy) / radial;
  }
  return [x, y];
}

function rotation(rxDeg, ryDeg, rzDeg) {
  const [a, b, c] = [rxDeg, ryDeg, rzDeg].map((d) => (d * Math.PI) / 180);
  const rx = [[1, 0, 0], [0, Math.cos(a), -Math.sin(a)], [0, Math.sin(a), Math.cos(a)]];
  const ry = [[Math.cos(b), 0, Math.sin(b)], [0, 1, 0], [-Math.sin(b), 0, Math.cos(b)]];
  const rz = [[Math.cos(c), -Math.sin(c), 0], [Math.sin(c), Math.cos(c), 0], [0, 0, 1]];
  const mul = (p, q) => p.map((row) => [0, 1, 2].map((j) => row[0] * q[0][j] + row[1] * q[1][j] + row[2] * q[2][j]));
  return mul(rz, mul(ry, rx));
}

// A checkerboard of cols x rows inner corners (squares of `square` m, a white margin of one
// square) whose centre sits at (ox, oy, distance) in the camera's frame, turned by rx, ry, rz.
function renderBoard(cam, { cols, rows, square }, pose, seed = 1) {
  const { width, height } = cam;
  const r = rotation(pose.rx, pose.ry, pose.rz);
  const centre = [((cols - 1) * square) / 2, ((rows - 1) * square) / 2];
  const t = [0, 1, 2].map((i) => [pose.ox, pose.oy, pose.distance][i] - r[i][0] * centre[0] - r[i][1] * centre[1]);
  const c1 = [r[0][0], r[1][0], r[2][0]];
  const c2 = [r[0][1], r[1][1], r[2][1]];
  const det3 = (a, b, c) => a[0] * (b[1] * c[2] - b[2] * c[1]) - b[0] * (a[1] * c[2] - a[2] * c[1]) + c[0] * (a[1] * b[2] - a[2] * b[1]);
  const shade = (u, v) => {
    const [x, y] = undistort(cam, u, v);
    const d = [-x, -y, -1];
    const rhs = [-t[0], -t[1], -t[2]];
    const den = det3(c1, c2, d);
    if (Math.abs(den) < 1e-12) return 110;
    const X = det3(rhs, c2, d) / den;
    const Y = det3(c1, rhs, d) / den;
    const lambda = det3(c1, c2, rhs) / den;
    if (lambda <= 0) return 110;
    const i = Math.floor(X / square) + 1;  // squares 0..cols across, the first inner corner at X = 0
    const j = Math.floor(Y / square) + 1;
    if (i < -1 || j < -1 || i > cols + 1 || j > rows + 1) return 110;  // beyond the margin
    if (i < 0 || j < 0 || i > cols || j > rows) return 235;            // the white margin
    return (i + j) % 2 === 0 ? 25 : 235;
  };
  const gray = new Uint8Array(width * height);
  let s = seed >>> 0;
  const rand = () => { s = (s * 1664525 + 1013904223) >>> 0; return s / 4294967296; };
  for (let v = 0; v < height; v += 1) {
    for (let u = 0; u < width; u += 1) {
      const sum = shade(u - 0.25, v - 0.25) + shade(u + 0.25, v - 0.25) + shade(u - 0.25, v + 0.25) + shade(u + 0.25, v + 0.25);
      gray[v * width + u] = Math.max(0, Math.min(255, Math.round(sum / 4 + (rand() + rand() + rand() - 1.5) * 2)));
    }
  }
  return { width, height, gray };
}

// A separable box blur, `passes` times (3 passes of radius r: a Gaussian of sigma about r).
function blur({ width, height, gray }, radius, passes = 3) {
  let a = Float32Array.from(gray);
  for (let p = 0; p < passes; p += 1) {
    for (const horizontal of [true, false]) {
      const b = new Float32Array(a.length);
      for (let y = 0; y < height; y += 1) {
        for (let x = 0; x < width; x += 1) {
          let sum = 0;
          let n = 0;
          for (let k = -radius; k <= radius; k += 1) {
            const xx = horizontal ? x + k : x;
            const yy = horizontal ? y : y + k;
            if (xx < 0 || yy < 0 || xx >= width || yy >= height) continue;
            sum += a[yy * width + xx];
            n += 1;
          }
          b[y * width + x] = sum / n;
        }
      }
      a = b;
    }
  }
  return { width, height, gray: Uint8Array.from(a, (v) => Math.round(v)) };
}

const crcTable = Array.from({ length: 256 }, (_, n) => {
  let c = n;
  for (let k = 0; k < 8; k += 1) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  return c >>> 0;
});
function crc32(buf) {
  let c = 0xffffffff;
  for (const b of buf) c = crcTable[(c ^ b) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

function png({ width, height, gray }) {
  const chunk = (type, data) => {
    const len = Buffer.alloc(4);
    len.writeUInt32BE(data.length);
    const body = Buffer.concat([Buffer.from(type, 'ascii'), data]);
    const crc = Buffer.alloc(4);
    crc.writeUInt32BE(crc32(body));
    return Buffer.concat([len, body, crc]);
  };
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(width, 0);
  ihdr.writeUInt32BE(height, 4);
  ihdr[8] = 8;  // bit depth
  ihdr[9] = 0;  // grey
  const raw = Buffer.alloc((width + 1) * height);
  for (let y = 0; y < height; y += 1) Buffer.from(gray.buffer, gray.byteOffset + y * width, width).copy(raw, y * (width + 1) + 1);
  return Buffer.concat([Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]), chunk('IHDR', ihdr),
    chunk('IDAT', zlib.deflateSync(raw)), chunk('IEND', Buffer.alloc(0))]);
}

// Poses that determine a lens: facing the camera, tilted by 30-40 degrees, near the picture's
// edges and corners (where the distortion is).
const poses = [
  { rx: 0, ry: 0, rz: 0, distance: 0.6, ox: 0, oy: 0 },
  { rx: 35, ry: 0, rz: 5, distance: 0.6, ox: 0.02, oy: 0 },
  { rx: -35, ry: 10, rz: -5, distance: 0.6, ox: -0.03, oy: 0.02 },
  { rx: 10, ry: 35, rz: 0, distance: 0.65, ox: 0.05, oy: -0.03 },
  { rx: 5, ry: -40, rz: 10, distance: 0.65, ox: -0.05, oy: 0.03 },
  { rx: 20, ry: 20, rz: 25, distance: 0.7, ox: 0.28, oy: 0.18 },
  { rx: -20, ry: -20, rz: -20, distance: 0.7, ox: -0.28, oy: -0.18 },
  { rx: 15, ry: -20, rz: 15, distance: 0.7, ox: 0.28, oy: -0.18 },
  { rx: -15, ry: 20, rz: -10, distance: 0.7, ox: -0.28, oy: 0.18 },
  { rx: 10, ry: -10, rz: 90, distance: 0.75, ox: 0, oy: 0 },
];

module.exports = { readIntrinsics, renderBoard, blur, png, poses, undistort };

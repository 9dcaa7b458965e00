// The web form's label-map target in real Chromium (Debian's chromium,
// npm playwright-core): the target_image file input, the parameters
// label, level and image_space from the schema, a job submitted through
// the form with them (its summary carries the label's figures), a dropped
// .nii.gz routed to target_image, and a label that selects nothing shown
// as the daemon's 422.  Usage: node web_image.mjs BASE TEMPLATE IMAGE
// Prints one JSON line per check: {desc, ok, detail}.
import { chromium } from 'playwright-core';

const [base, template, image] = process.argv.slice(2);
const report = (desc, ok, detail = '') => console.log(JSON.stringify({ desc, ok: !!ok, detail: String(detail).slice(0, 2000) }));

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--disable-dev-shm-usage'],
});
try {
  const page = await (await browser.newContext()).newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  await page.goto(`${base}/`);
  await page.waitForSelector('#p-clamp');
  const fields = await page.evaluate(() => ({
    file: !!document.querySelector('#f-target_image[type=file]'),
    label: !!document.querySelector('#p-label'),
    level: !!document.querySelector('#p-level'),
    spaces: [...document.querySelectorAll('#p-image_space option')].map((o) => o.value),
  }));
  report('the form has the target_image file input and the label, level and image_space fields',
    fields.file && fields.label && fields.level && fields.spaces.includes('lps') && fields.spaces.includes('ras'),
    JSON.stringify(fields));

  const fill = async (label) => {
    await page.setInputFiles('#f-template', template);
    await page.setInputFiles('#f-target_image', image);
    await page.selectOption('#p-clamp', 'ball');
    for (const [id, v] of [['x', 4], ['y', 39], ['z', 9], ['radius', 4.5]]) await page.fill(`#p-clamp-${id}`, String(v));
    await page.fill('#p-label', String(label));
    await page.selectOption('#p-image_space', 'lps');
    await page.fill('#p-max_iter', '10');
  };
  await fill(1);
  await page.click('#submit');
  await page.waitForFunction(() => ['successful', 'failed'].includes(document.querySelector('#status').textContent), null, { timeout: 90000 });
  const status = await page.$eval('#status', (e) => e.textContent);
  const id = await page.$eval('#job-id', (e) => e.textContent);
  const summary = await (await fetch(`${base}/v1/jobs/${id}/results`)).json();
  const ti = summary.target_image || {};
  report('a job through the form with target_image and label 1: successful, summary.target_image says 1921 voxels of label 1',
    status === 'successful' && ti.voxels === 1921 && ti.label === 1 && ti.image_space === 'lps',
    `${status} ${JSON.stringify(ti)}`);

  await fill(9);
  await page.click('#submit');
  await page.waitForFunction(() => /label-empty/.test(document.querySelector('#job-form').textContent), null, { timeout: 30000 })
    .catch(() => {});
  const shown = await page.$eval('#job-form', (e) => [...e.querySelectorAll('.err')].map((s) => s.textContent).join(' '));
  report('label 9 (no voxel): the daemon\'s 422 (label-empty) shown in the form', /label-empty/.test(shown), shown);

  const routed = await page.evaluate(() => {
    const dt = new DataTransfer();
    dt.items.add(new File([new Uint8Array([31, 139])], 'sphere.nii.gz'));
    document.querySelector('#job-form').dispatchEvent(new DragEvent('drop', { dataTransfer: dt, bubbles: true, cancelable: true }));
    return document.querySelector('#f-target_image').files[0]?.name;
  });
  report('a dropped sphere.nii.gz goes to target_image', routed === 'sphere.nii.gz', routed);
  report('no page errors', errors.length === 0, errors.join('\n'));
} catch (e) {
  report('the browser checks run', false, e.stack);
} finally {
  await browser.close();
}

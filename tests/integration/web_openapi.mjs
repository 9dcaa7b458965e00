// Validates what a running shapematchd serves (issue 11): the OpenAPI
// document at BASE/v1/openapi.yaml with @apidevtools/swagger-parser,
// fetched and resolved over HTTP exactly as served (its $refs to
// params.schema.json and events.schema.json included), then
// GET /v1/processes/match against the document's own Process schema and
// GET /v1/conformance against confClasses (ajv, JSON Schema 2020-12, the
// dialect of OpenAPI 3.1); ExecuteRequest lists the described inputs
// (landmarks and image included) and validates requests with them.
// Prints one JSON line per check ({ok, desc, detail}) for the shell
// suite (web_openapi.sh) to report.
// Usage: node web_openapi.mjs BASE
import SwaggerParser from '@apidevtools/swagger-parser';
import Ajv2020 from 'ajv/dist/2020.js';

const base = process.argv[2];
let failed = 0;
const ok = (desc) => console.log(JSON.stringify({ ok: true, desc }));
const notOk = (desc, detail) => {
  failed++;
  console.log(JSON.stringify({ ok: false, desc, detail: String(detail).slice(0, 3000) }));
};

async function getJson(path) {
  const r = await fetch(base + path, { headers: { Accept: 'application/json' } });
  if (r.status !== 200) throw new Error(`${path}: status ${r.status}`);
  return r.json();
}

function check(api, schemaName, doc, desc) {
  const ajv = new Ajv2020({ strict: false, allErrors: true, validateFormats: false });
  const schema = api.components.schemas[schemaName];
  if (!schema) return notOk(desc, `no components.schemas.${schemaName}`);
  const validate = ajv.compile(schema);
  if (validate(doc)) ok(desc);
  else notOk(desc, JSON.stringify(validate.errors, null, 2));
}

let api;
try {
  // validate() dereferences: every $ref must resolve from the served URL
  // the daemon under test is on loopback, which the resolver refuses by
  // default (its guard against requests to internal hosts)
  api = await SwaggerParser.validate(`${base}/v1/openapi.yaml`,
                                     { resolve: { http: { safeUrlResolver: false } } });
  ok(`the served /v1/openapi.yaml is a valid OpenAPI ${api.openapi} document, every $ref resolved as served`);
} catch (e) {
  notOk('the served /v1/openapi.yaml validates', e.message);
}
if (api) {
  try {
    check(api, 'Process', await getJson('/v1/processes/match'),
          'GET /v1/processes/match validates against the document\'s Process schema');
  } catch (e) {
    notOk('GET /v1/processes/match', e.message);
  }
  // the execute request's inputs are the process description's (the
  // daemon accepts every part of the multipart upload inline: smd_ogc.c)
  try {
    const described = Object.keys((await getJson('/v1/processes/match')).inputs).sort();
    const schema = api.components.schemas.ExecuteRequest.properties.inputs.properties;
    const executable = Object.keys(schema).sort();
    if (JSON.stringify(described) === JSON.stringify(executable)) {
      ok(`ExecuteRequest's inputs are GET /v1/processes/match's: ${executable.join(', ')}`);
    } else {
      notOk('ExecuteRequest inputs = the process description\'s inputs',
            `described ${described.join(',')}; ExecuteRequest ${executable.join(',')}`);
    }
    for (const part of ['template_landmarks', 'target_landmarks', 'target_image']) {
      if (!described.includes(part)) notOk(`the process description lists ${part}`, described);
    }
    const file = { value: 'MCwwCjEsMAo=', mediaType: 'text/csv' };
    const clamp = { kind: 'ball', center: [0, 0], radius: 0.1 };
    check(api, 'ExecuteRequest',
          { inputs: { template: file, target_mesh: file, target_sol: file,
                      template_landmarks: file, target_landmarks: file,
                      params: { clamp, align: 'rigid' } } },
          'an execute request with template_landmarks and target_landmarks validates');
    check(api, 'ExecuteRequest',
          { inputs: { template: file, target_image: file, params: { clamp, label: 1 } } },
          'an execute request with target_image validates');
    const ajv = new Ajv2020({ strict: false, allErrors: true, validateFormats: false });
    const validate = ajv.compile(api.components.schemas.ExecuteRequest);
    if (!validate({ inputs: { template: file, colour: file, params: { clamp } } })) {
      ok('an execute request with an unknown input does not validate');
    } else {
      notOk('an unknown input is refused by ExecuteRequest', 'it validated');
    }
  } catch (e) {
    notOk('ExecuteRequest against the process description', e.message);
  }
  try {
    check(api, 'confClasses', await getJson('/v1/conformance'),
          'GET /v1/conformance validates against confClasses');
  } catch (e) {
    notOk('GET /v1/conformance', e.message);
  }
  try {
    check(api, 'LandingPage', await getJson('/v1'), 'GET /v1 validates against LandingPage');
  } catch (e) {
    notOk('GET /v1', e.message);
  }
}
process.exit(failed ? 1 : 0);

// `simgate mcp` against the Model Context Protocol's own client (@modelcontextprotocol/sdk,
// nobody on the team wrote it) over stdio, as a desktop agent launches it: the SDK spawns
// `simgate mcp --model MODEL --plugin-path DIR` (the simulation runs in that process, served by
// an mcp transport its standard input and output are bridged to), lists the tools, subscribes
// to a stream's resource (its updates forwarded from the session's GET stream), pauses the
// simulation and steps it with progress, and closes (standard input ends: the process exits).
// Exit 77 (skipped) without the SDK (scripts/test installs it).
'use strict';
const path = require('path');

let Client, StdioClientTransport, ResourceUpdatedNotificationSchema;
try {
  ({ Client } = require(path.join(__dirname, 'node_modules/@modelcontextprotocol/sdk/dist/cjs/client/index.js')));
  ({ StdioClientTransport } = require(path.join(__dirname, 'node_modules/@modelcontextprotocol/sdk/dist/cjs/client/stdio.js')));
  ({ ResourceUpdatedNotificationSchema } = require(path.join(__dirname, 'node_modules/@modelcontextprotocol/sdk/dist/cjs/types.js')));
} catch (e) {
  console.log('SKIP: @modelcontextprotocol/sdk is not installed (scripts/test installs it): ' + e.message);
  process.exit(77);
}

function check(condition, what) {
  if (!condition) throw new Error('check failed: ' + what);
}

async function main([simgate, model, pluginDir]) {
  const transport = new StdioClientTransport({
    command: simgate, args: ['mcp', '--model', model, '--plugin-path', pluginDir], stderr: 'inherit',
  });
  const client = new Client({ name: 'simgate-mcp-stdio-test', version: '1.0.0' });
  await client.connect(transport);
  const { tools } = await client.listTools();
  const names = tools.map((t) => t.name);
  console.log(`tools/list over stdio: ${tools.length} tools`);
  check(names.includes('simulation_step') && names.includes('simulation_list_robots'), 'the simulation tools are listed');
  const robots = await client.callTool({ name: 'simulation_list_robots', arguments: {} });
  check(!robots.isError && robots.structuredContent.result.length >= 1, 'the model\'s robots: ' + JSON.stringify(robots.structuredContent));
  // a stream's resource, subscribed: its updates come through the bridge (the session's GET
  // stream, forwarded to standard output)
  const { resources } = await client.listResources();
  const stream = resources.find((r) => r.uri.startsWith('simgate://streams/'));
  check(stream, 'the model\'s streams are resources: ' + resources.map((r) => r.uri));
  const updates = [];
  client.setNotificationHandler(ResourceUpdatedNotificationSchema, (n) => updates.push(n.params.uri));
  await client.subscribeResource({ uri: stream.uri });
  const until = Date.now() + 15000;
  while (updates.length < 1 && Date.now() < until) await new Promise((r) => setTimeout(r, 20));
  check(updates.length >= 1 && updates[0] === stream.uri, `${stream.uri} updated over stdio (${updates.length})`);
  const read = await client.readResource({ uri: stream.uri });
  check(JSON.parse(read.contents[0].text).seq >= 1, 'its sample reads over stdio: ' + read.contents[0].text.slice(0, 120));
  await client.unsubscribeResource({ uri: stream.uri });
  const paused = await client.callTool({ name: 'simulation_pause', arguments: {} });
  check(!paused.isError, 'pause: ' + JSON.stringify(paused));
  const reports = [];
  const stepped = await client.callTool({ name: 'simulation_step', arguments: { n: 20000 } }, undefined,
                                        { onprogress: (p) => reports.push(p), timeout: 60000 });
  check(!stepped.isError && stepped.structuredContent.steps_done === 20000, 'step 20000: ' + JSON.stringify(stepped.structuredContent));
  console.log(`simulation_step 20000: ${reports.length} progress reports over stdio`);
  check(reports.length >= 1, 'the step reported its progress through the bridge');
  for (const r of reports) check(r.total === 20000 && r.progress <= 20000, 'a step report says the steps done of 20000: ' + JSON.stringify(r));
  const bad = await client.callTool({ name: 'simulation_step', arguments: { n: 'many' } });
  check(bad.isError, 'a wrong argument over stdio is a tool error: ' + JSON.stringify(bad));
  await client.close();
  console.log('PASS: simgate mcp serves an MCP client over stdio');
}

const overall = setTimeout(() => {
  console.error('FAIL: the test took longer than 120 s');
  process.exit(1);
}, 120000);
main(process.argv.slice(2)).then(() => clearTimeout(overall)).catch((e) => {
  console.error('FAIL: ' + (e && e.stack ? e.stack : e));
  process.exit(1);
});

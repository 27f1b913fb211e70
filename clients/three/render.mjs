// Drives main.js in Debian's Chromium (software WebGL2) and writes the frame as a PFM
// (linear float RGB, rows bottom to top) and its alpha as a second PFM.
//
//   node render.mjs --files DIR --scene NAME.glb --grid NAME.ktx2 --eye X,Y,Z --target X,Y,Z
//        --fov DEG --width W --height H [--control none|pi|swap] [--spheres X,Y,Z,R;...]
//        --out FRAME.pfm
//
// The page, three.js and the files in DIR are served on 127.0.0.1 only; Chromium is
// LIGHTVOL_CHROMIUM or /usr/bin/chromium.
import { createServer } from 'node:http';
import { readFile, writeFile, rename } from 'node:fs/promises';
import { extname, join, normalize, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const here = dirname( fileURLToPath( import.meta.url ) );
const args = {};
for ( let i = 2; i < process.argv.length; i += 2 ) args[ process.argv[ i ].replace( /^--/, '' ) ] = process.argv[ i + 1 ];
for ( const k of [ 'files', 'scene', 'grid', 'eye', 'target', 'fov', 'width', 'height', 'out' ] ) {

	if ( args[ k ] === undefined ) {

		console.error( `render.mjs: missing --${k}` );
		process.exit( 2 );

	}

}

const types = { '.html': 'text/html', '.js': 'text/javascript', '.json': 'application/json', '.glb': 'model/gltf-binary', '.ktx2': 'image/ktx2' };
const server = createServer( async ( req, res ) => {

	const path = normalize( decodeURIComponent( new URL( req.url, 'http://x' ).pathname ) );
	const root = path.startsWith( '/files/' ) ? join( args.files, path.slice( 7 ) ) : join( here, path );
	if ( path.includes( '..' ) ) {

		res.writeHead( 403 ).end();
		return;

	}

	try {

		const body = await readFile( root.endsWith( '/' ) ? root + 'index.html' : root );
		res.writeHead( 200, { 'content-type': types[ extname( root ) ] || 'application/octet-stream' } ).end( body );

	} catch {

		res.writeHead( 404 ).end();

	}

} );
await new Promise( ( ok ) => server.listen( 0, '127.0.0.1', ok ) );
const port = server.address().port;

const browser = await chromium.launch( {
	executablePath: process.env.LIGHTVOL_CHROMIUM || '/usr/bin/chromium',
	args: [ '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
		'--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run', '--disable-quic' ],
} );
let code = 0;
try {

	const page = await browser.newPage();
	page.on( 'console', ( m ) => console.error( `page: ${m.text()}` ) );
	const q = new URLSearchParams( {
		scene: `/files/${args.scene}`, grid: `/files/${args.grid}`, eye: args.eye, target: args.target,
		fov: args.fov, width: args.width, height: args.height, control: args.control || 'none',
		spheres: args.spheres || '',
	} );
	await page.goto( `http://127.0.0.1:${port}/index.html?${q}` );
	await page.waitForFunction( () => window.lightvolFrame !== undefined, null, { timeout: 120000 } );
	const frame = await page.evaluate( () => window.lightvolFrame );
	if ( frame.error ) throw new Error( frame.error );
	const { width, height, rgba } = frame;
	const pfm = ( channels ) => {

		const header = Buffer.from( `PF\n${width} ${height}\n-1.0\n` );
		const body = Buffer.alloc( width * height * 12 );
		for ( let i = 0; i < width * height; i ++ ) for ( let c = 0; c < 3; c ++ ) body.writeFloatLE( channels( i, c ), ( i * 3 + c ) * 4 );
		return Buffer.concat( [ header, body ] );

	};
	const write = async ( path, bytes ) => {

		await writeFile( path + '.part', bytes );
		await rename( path + '.part', path );

	};
	await write( args.out, pfm( ( i, c ) => rgba[ i * 4 + c ] ) );
	await write( args.out.replace( /\.pfm$/, '' ) + '.alpha.pfm', pfm( ( i ) => rgba[ i * 4 + 3 ] ) );
	console.log( `wrote ${args.out} (${width}x${height})` );

} catch ( e ) {

	console.error( `render.mjs: ${e.message}` );
	code = 1;

} finally {

	await browser.close();
	server.close();

}

process.exit( code );

// Renders a glTF scene lit only by a lightvol volume (loadLightvolGrid), to a float target,
// and leaves the linear pixels in window.lightvolFrame for the driver (render.mjs).
// Query: scene, grid (URLs), eye, target (x,y,z in the file's frame), fov (vertical,
// degrees), width, height, control (none | pi | swap: deliberately wrong texels),
// spheres (optional X,Y,Z,R;...: white spheres for known points).
import {
	DataUtils, FloatType, Mesh, MeshLambertMaterial, NearestFilter, PerspectiveCamera, RGBAFormat,
	Scene, SphereGeometry, Vector3, WebGLRenderer, WebGLRenderTarget
} from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { loadLightvolGrid } from './lightvol-grid.js';

const q = new URLSearchParams( location.search );
const vec = ( s ) => new Vector3( ...s.split( ',' ).map( Number ) );

// White-furnace comparable shading: Lambert's indirect diffuse is irradiance · albedo / π
// with nothing else added (no ambient light, no emission, no tone mapping).
function lambert( m ) {

	return new MeshLambertMaterial( { color: m.color, map: m.map, side: m.side } );

}

// Negative controls: texels π times too bright, or the atlas laid out along swapped x and z.
function corrupt( grid, control ) {

	const img = grid.texture.image;
	if ( control === 'pi' ) {

		for ( let i = 0; i < img.data.length; i ++ ) img.data[ i ] = DataUtils.toHalfFloat( DataUtils.fromHalfFloat( img.data[ i ] ) * Math.PI );

	} else if ( control === 'swap' ) {

		const [ nx, ny, nz ] = grid.resolution.toArray();
		const out = new Uint16Array( img.data.length );
		const src = ( t, x, y, z ) => ( ( ( t * ( nz + 2 ) + z + 1 ) * ny + y ) * nx + x ) * 4;
		const dst = ( t, x, y, z ) => ( ( ( t * ( nx + 2 ) + z + 1 ) * ny + y ) * nz + x ) * 4;
		for ( let t = 0; t < 7; t ++ ) for ( let z = - 1; z <= nx; z ++ ) for ( let y = 0; y < ny; y ++ ) for ( let x = 0; x < nz; x ++ ) {

			const s = src( t, Math.min( Math.max( z, 0 ), nx - 1 ), y, x );
			for ( let c = 0; c < 4; c ++ ) out[ dst( t, x, y, z ) + c ] = img.data[ s + c ];

		}

		img.data = out;
		img.width = nz;
		img.depth = 7 * ( nx + 2 );
		grid.resolution.set( nz, ny, nx );

	}

	grid.texture.mipmaps = [ { data: img.data, width: img.width, height: img.height, depth: img.depth } ];
	grid.texture.needsUpdate = true;

}

async function main() {

	const width = Number( q.get( 'width' ) ), height = Number( q.get( 'height' ) );
	const renderer = new WebGLRenderer( { antialias: false } );
	renderer.setSize( width, height, false );

	const scene = new Scene();
	const gltf = await new GLTFLoader().loadAsync( q.get( 'scene' ) );
	gltf.scene.traverse( ( o ) => {

		if ( o.isMesh ) o.material = Array.isArray( o.material ) ? o.material.map( lambert ) : lambert( o.material );

	} );
	scene.add( gltf.scene );
	for ( const sphere of ( q.get( 'spheres' ) || '' ).split( ';' ).filter( Boolean ) ) {

		const [ x, y, z, r ] = sphere.split( ',' ).map( Number );
		const ball = new Mesh( new SphereGeometry( r, 256, 128 ), new MeshLambertMaterial( { color: 0xffffff } ) );
		ball.position.set( x, y, z );
		scene.add( ball );

	}

	const grid = await loadLightvolGrid( renderer, q.get( 'grid' ) );
	corrupt( grid, q.get( 'control' ) || 'none' );
	scene.add( grid );

	const eye = vec( q.get( 'eye' ) ), target = vec( q.get( 'target' ) );
	const camera = new PerspectiveCamera( Number( q.get( 'fov' ) ), width / height, 0.01, 1000 );
	camera.position.copy( eye );
	camera.lookAt( target );

	const rt = new WebGLRenderTarget( width, height, { type: FloatType, format: RGBAFormat, minFilter: NearestFilter, magFilter: NearestFilter } );
	renderer.setRenderTarget( rt );
	renderer.setClearColor( 0x000000, 0 );
	renderer.render( scene, camera );
	const rgba = new Float32Array( width * height * 4 );
	renderer.readRenderTargetPixels( rt, 0, 0, width, height, rgba );
	window.lightvolFrame = { width, height, rgba: Array.from( rgba ) };

}

main().catch( ( e ) => {

	window.lightvolFrame = { error: String( e && e.stack || e ) };

} );

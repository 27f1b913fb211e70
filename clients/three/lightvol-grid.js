import { LinearFilter } from 'three';
import { KTX2Loader } from 'three/addons/loaders/KTX2Loader.js';
import { LightProbeGridWebGL } from 'three/addons/lighting/LightProbeGridWebGL.js';

// Loads `lightvol export VOLUME.exr --format three -o grid.ktx2` (the texture and the
// grid.ktx2.json beside it) as a three.js LightProbeGrid. Add the result to the scene.
export async function loadLightvolGrid( renderer, url ) {

	const placement = ( await ( await fetch( url + '.json' ) ).json() ).three;
	const texture = await new KTX2Loader().detectSupport( renderer ).loadAsync( url );
	texture.minFilter = texture.magFilter = LinearFilter; // the loader leaves raw textures nearest
	texture.needsUpdate = true;

	const [ width, height, depth ] = placement.size;
	const [ nx, ny, nz ] = placement.resolution;
	const grid = new LightProbeGridWebGL( width, height, depth, nx, ny, nz );
	grid.position.fromArray( placement.position );
	grid.updateBoundingBox(); // the box follows the position only when asked
	grid.texture = texture;
	return grid;

}

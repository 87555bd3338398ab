fn main() {
    print!("{}", agentstar_scene::api_markdown());
}

!> The model of a rank built from the configuration, its body and its local lattice
!> (model_init, documented at its interface in iem_model.f90).
submodule (iem_model) iem_model_init
  use iem_time_function, only: time_function
  implicit none

contains

  !> Documented at its interface in iem_model.f90.
  module procedure model_init
    integer :: l, q, b, n, c, ld, ierr, mt, nm, nd, na, nf, corner(4)
    integer, allocatable :: cnt(:, :)
    logical, allocatable :: taken(:, :), mask(:)
    real(wp), allocatable :: weight(:), mcell(:)
    real(wp) :: er_pos(3), er_neg(3)
    real(wp), parameter :: elastic_er = 1.0e300_wp
    type(alloc_guard_t) :: g
    type(fracture_law_t), allocatable :: laws(:)
    real(wp), allocatable :: centres(:, :)
    logical :: ok

    this%grid = body%grid
    nm = size(cfg%materials)
    allocate(this%ks(nm), this%densities(nm), mcell(nm))
    do mt = 1, nm
      this%ks(mt) = cell_constants(cfg%materials(mt)%young, cfg%materials(mt)%poisson, &
                                   cfg%geometry%plane == 'strain', body%grid%lx, &
                                   body%grid%ly, body%grid%thickness, &
                                   bending=cfg%geometry%cell == 'bending')
      this%densities(mt) = cfg%materials(mt)%density
      mcell(mt) = 0.25_wp*this%densities(mt)*body%grid%lx*body%grid%ly*body%grid%thickness
    end do
    this%k = this%ks(1)
    this%density = this%densities(1)
    this%mixed = nm > 1
    this%alpha = cfg%damping%alpha
    this%beta = cfg%damping%beta
    this%omega_cap = 0.0_wp
    this%n_state = 4
    if (cfg%damping%kind == 'capped') then
      this%omega_cap = 2.0_wp*pi*cfg%damping%cap_frequency
      this%beta = capped_beta(cfg%damping%ratio, 2.0_wp*pi*cfg%damping%frequency, this%omega_cap)
      this%n_state = 6
    end if
    this%sum_in_acc = cfg%run%analysis /= 'static' .and. cfg%run%integrator == 'verlet' .and. &
                      this%n_state == 4
    this%nonlinear = any(cfg%materials(:)%nonlinear)
    if (this%nonlinear) then
      ! materials without nonlinear springs keep theirs on the elastic line (a reference
      ! strain so large that psi = e to the last bit)
      do mt = 1, nm
        associate(mat => cfg%materials(mt))
          if (mat%nonlinear) then
            call reference_strains(mat%young, mat%poisson, cfg%geometry%plane == 'strain', &
                                   mat%tensile_strength, mat%compressive_strength, &
                                   mat%shear_strength, er_pos, er_neg)
          else
            er_pos = elastic_er
            er_neg = elastic_er
          end if
          if (mt == 1) then
            ! the springs' curves pay where trial evaluations come between commits (RK4's
            ! stages, the static relaxation's iterations), not where each one commits
            call this%nl%init(lat%n_cells, er_pos, er_neg, [this%ks(1)%ce, this%ks(1)%ch, &
                              this%ks(1)%cg], maxval(cfg%materials(:)%history_depth), g, nm, &
                              curves=cfg%run%analysis == 'static' .or. &
                                     cfg%run%integrator /= 'verlet')
            if (g%failed) then
              call g%pass(guard)
              return
            end if
          else
            call this%nl%set_law(mt, er_pos, er_neg, [this%ks(mt)%ce, this%ks(mt)%ch, &
                                 this%ks(mt)%cg])
          end if
        end associate
      end do
    end if
    ! fracture: the laws of the materials (checked against the cells when the input was read)
    this%fracture = any(cfg%materials(:)%fracture) .or. size(body%cracks) > 0
    if (this%fracture) then
      allocate(laws(nm))
      do mt = 1, nm
        call material_fracture_law(cfg%materials(mt), cfg%geometry%plane == 'strain', &
                                   body%grid%lx, body%grid%ly, laws(mt), ok, q)
      end do
      call this%fr%init(laws, lat%n_cells, g)
      if (g%failed) then
        call g%pass(guard)
        return
      end if
      if (size(body%cracks) > 0) then
        allocate(centres(2, lat%n_cells))
        do c = 1, lat%n_cells
          centres(:, c) = 0.25_wp*(lat%node_xy(lat%cell_nodes(1, c)) + &
                          lat%node_xy(lat%cell_nodes(2, c)) + lat%node_xy(lat%cell_nodes(3, c)) + &
                          lat%node_xy(lat%cell_nodes(4, c)))
        end do
        call this%fr%precut(body%cracks, centres)
      end if
    end if
    nf = lat%n_local
    if (this%sum_in_acc) nf = 0
    allocate(this%mass(lat%n_owned), cnt(nm, lat%n_owned), this%f(2, nf), &
             taken(2, lat%n_owned), mask(lat%n_owned), weight(lat%n_owned), stat=ierr)
    call g%note(ierr, 'the model of the rank', (33.0_wp + 4*nm)*lat%n_owned + 16.0_wp*nf)
    if (g%failed) then
      call g%pass(guard)
      return
    end if
    ! lumped masses: a quarter of each cell at each corner, by material
    cnt = 0
    do c = 1, lat%n_cells
      corner = lat%corners(c)
      do q = 1, 4
        l = corner(q)
        if (l <= lat%n_owned) cnt(lat%mat(c), l) = cnt(lat%mat(c), l) + 1
      end do
    end do
    do l = 1, lat%n_owned
      this%mass(l) = 0.0_wp
      do mt = 1, nm
        if (cnt(mt, l) > 0) this%mass(l) = this%mass(l) + mcell(mt)*cnt(mt, l)
      end do
    end do
    this%f = 0.0_wp
    n_selected = 0

    ! boundary conditions: a later &bc overrides an earlier one on the same dof
    n = 0
    do b = 1, size(cfg%bcs)
      call select_nodes(cfg%bcs(b)%set, body, lat, mask)
      n_selected(b) = count(mask)
      n = n + count(mask)*count(cfg%bcs(b)%dof)
    end do
    allocate(this%bc_node(n), this%bc_comp(n), this%bc_id(n), stat=ierr)
    call g%note(ierr, 'the prescribed dofs of the rank', 12.0_wp*n)
    if (g%failed) then
      call g%pass(guard)
      return
    end if
    allocate(this%bc_velocity(2, size(cfg%bcs)), this%bc_tf(size(cfg%bcs)))
    allocate(this%bc_release(size(cfg%bcs)))
    this%bc_release = cfg%bcs(:)%t_release
    taken = .false.
    n = 0
    do b = 1, size(cfg%bcs)
      this%bc_velocity(:, b) = 0.0_wp
      if (cfg%bcs(b)%kind == 'velocity') this%bc_velocity(:, b) = cfg%bcs(b)%velocity
      this%bc_tf(b) = time_function(cfg%bcs(b)%tf)
      call select_nodes(cfg%bcs(b)%set, body, lat, mask)
      do l = 1, lat%n_owned
        if (.not. mask(l)) cycle
        do c = 1, 2
          if (.not. cfg%bcs(b)%dof(c)) cycle
          if (taken(c, l)) then
            do q = 1, n
              if (this%bc_node(q) == l .and. this%bc_comp(q) == c) this%bc_id(q) = b
            end do
          else
            n = n + 1
            this%bc_node(n) = l
            this%bc_comp(n) = c
            this%bc_id(n) = b
            taken(c, l) = .true.
          end if
        end do
      end do
    end do
    this%bc_node = this%bc_node(1:n)
    this%bc_comp = this%bc_comp(1:n)
    this%bc_id = this%bc_id(1:n)

    ! loads
    n = 0
    do ld = 1, size(cfg%loads)
      call select_nodes(cfg%loads(ld)%set, body, lat, mask)
      n_selected(size(cfg%bcs) + ld) = count(mask)
      n = n + count(mask)
    end do
    allocate(this%load_node(n), this%load_id(n), this%load_force(2, n), stat=ierr)
    call g%note(ierr, 'the loaded nodes of the rank', 24.0_wp*n)
    if (g%failed) then
      call g%pass(guard)
      return
    end if
    allocate(this%load_tf(size(cfg%loads)), this%load_scale(size(cfg%loads)))
    this%load_scale = huge(1.0_wp)
    n = 0
    do ld = 1, size(cfg%loads)
      this%load_tf(ld) = time_function(cfg%loads(ld)%tf)
      call select_nodes(cfg%loads(ld)%set, body, lat, mask, weight)
      do l = 1, lat%n_owned
        if (.not. mask(l)) cycle
        n = n + 1
        this%load_node(n) = l
        this%load_id(n) = ld
        select case (trim(cfg%loads(ld)%kind))
        case ('nodal')
          this%load_force(:, n) = cfg%loads(ld)%value
        case ('edge')
          this%load_force(:, n) = cfg%loads(ld)%value*weight(l)*body%grid%thickness
        case ('gravity')
          this%load_force(:, n) = cfg%loads(ld)%value*this%mass(l)
        end select
      end do
    end do
    call index_loaded_nodes(this, lat%n_owned)
    call this%split%init(lat%cells, lat%n_owned, lat%n_local)
    call order_by_node(this%bc_node, lat%n_owned, this%bc_by_node)
    call this%set_bands(lat)
    this%rows = kernel_rows()
    allocate(this%f_bc(size(this%bc_node)))
    ! the damping powers only with that damping
    nd = 0
    if (this%beta > 0.0_wp) nd = lat%n_cells
    na = 0
    if (this%alpha > 0.0_wp) na = lat%n_owned
    allocate(this%pw_cell(nd), this%wd_cell(nd), this%pw_node(na), this%wd_node(na), &
             this%pe_slot(size(this%ext_node)), this%pr_bc(size(this%bc_node)), &
             this%r_bc(size(this%bc_node)), this%pr_on(size(this%bc_node)), stat=ierr)
    call g%note(ierr, 'the energy terms of the rank', 16.0_wp*nd + &
                8.0_wp*(2*na + 2*size(this%bc_node)) + 4.0_wp*size(this%bc_node))
    if (g%failed) then
      call g%pass(guard)
      return
    end if
    call this%en_sum%reset()
    this%pw_cell = 0.0_wp
    this%wd_cell = 0.0_wp
    this%pw_node = 0.0_wp
    this%wd_node = 0.0_wp
    this%pe_slot = 0.0_wp
    this%pr_bc = 0.0_wp
    this%r_bc = 0.0_wp
    this%pr_on = .false.
    call this%w_ext_acc%reset()
    call this%w_damp_acc%reset()
  end procedure model_init

  !> The slots of the loaded nodes (ascending node order) for the compact external forces.
  subroutine index_loaded_nodes(this, n_owned)
    type(model_t), intent(inout) :: this
    integer, intent(in) :: n_owned
    integer, allocatable :: slot_of(:)
    integer :: n, l, q
    allocate(slot_of(n_owned))
    slot_of = 0
    do n = 1, size(this%load_node)
      slot_of(this%load_node(n)) = 1
    end do
    allocate(this%ext_node(count(slot_of > 0)))
    n = 0
    do l = 1, n_owned
      if (slot_of(l) == 0) cycle
      n = n + 1
      this%ext_node(n) = l
      slot_of(l) = n
    end do
    allocate(this%fext(2, n), this%load_slot(size(this%load_node)), &
             this%bc_slot(size(this%bc_node)))
    this%fext = 0.0_wp
    do n = 1, size(this%load_node)
      this%load_slot(n) = slot_of(this%load_node(n))
    end do
    do q = 1, size(this%bc_node)
      this%bc_slot(q) = slot_of(this%bc_node(q))
    end do
  end subroutine index_loaded_nodes
end submodule iem_model_init
